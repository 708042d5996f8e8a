"""The page ``onebit follow --serve-web`` serves, opened in a real browser.

Debian's Chromium, headless, with its software renderer (SwiftShader through ANGLE: no GPU),
driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``: fd 3 carries the
commands in, fd 4 the replies out, each a JSON text ended by a NUL byte -- nothing to install).
While a replayed follow is half-way, the page is opened; the test waits until the viewer holds
the follow's recording, then checks

* **the data arrived** -- the viewer's own state (``window._handle.viewer_state()``, the
  encoded ``GetStateResponse`` of Rerun's viewer control API) names the follow's recording id
  (read back from ``follow.rrd``), the ``t`` timeline, and the views of the live blueprint the
  follow sent;
* **the page draws it** -- a screenshot that is not blank (many colours) and holds pixels of
  the intruder tracker's colour, which only the published estimates are drawn in.

If the renderer cannot start, the page never gets that far: the failure message carries the
console's renderer lines and errors (the reason). It takes 40-90 s on a shared 2-core machine
(the viewer's 40 MB wasm compiled and started on a software renderer), so it is marked
``browser`` and left out of ``make test``; ``make browser-test`` runs it (installing Chromium
from Debian if missing). Without Chromium it skips, saying so.
"""

from __future__ import annotations

import base64
import io
import json
import os
import shutil
import subprocess
import threading
import time

import numpy as np
import pytest

from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.follow import FollowConfig, follow
from onebit.pipeline.stages import LOOKS
from onebit.viz.colors import tracker_color
from onebit.viz.families import Look
from onebit.viz.inspect import store_ids
from onebit.viz.live import WebServe

pytestmark = pytest.mark.browser

CHROMIUM = next((p for p in ("/usr/bin/chromium", shutil.which("chromium") or "") if p and os.path.exists(p)), None)
#: Debian's headless flags that work without a sandbox, GPU or network
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)
#: seconds the page may take to show the stream (the wasm on a software renderer, two busy cores)
PAGE_TIMEOUT_S = 240.0


class DevTools:
    """The DevTools protocol of a headless Chromium over ``--remote-debugging-pipe``."""

    def __init__(self, exe: str, profile: str, log, *, size: tuple[int, int] = (1280, 800)):
        cmd_r, self._cmd_w = os.pipe()
        self._out_r, out_w = os.pipe()

        def onto_3_and_4() -> None:  # runs in the child: the pipe ends Chromium expects
            os.dup2(cmd_r, 3)
            os.dup2(out_w, 4)

        self.proc = subprocess.Popen(
            [exe, *FLAGS, f"--user-data-dir={profile}", "--remote-debugging-pipe", f"--window-size={size[0]},{size[1]}"]
            + ["about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            preexec_fn=onto_3_and_4,  # noqa: PLW1509
            close_fds=False,
        )
        os.close(cmd_r)
        os.close(out_w)
        self.events: list[dict] = []
        self._replies: dict[int, dict] = {}
        self._last = 0
        self._cv = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        buf = b""
        while chunk := os.read(self._out_r, 1 << 16):
            buf += chunk
            *messages, buf = buf.split(b"\0")
            with self._cv:
                for m in messages:
                    d = json.loads(m)
                    if "id" in d:
                        self._replies[d["id"]] = d
                    else:
                        self.events.append(d)
                self._cv.notify_all()

    def call(self, method: str, session: str | None = None, *, timeout: float = 60.0, **params):
        self._last += 1
        i = self._last
        msg = {"id": i, "method": method, "params": params, **({"sessionId": session} if session else {})}
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        with self._cv:
            if not self._cv.wait_for(lambda: i in self._replies, timeout):
                raise TimeoutError(f"DevTools {method}: no reply in {timeout} s")
            reply = self._replies.pop(i)
        if "error" in reply:
            raise RuntimeError(f"DevTools {method}: {reply['error']}")
        return reply["result"]

    def console(self) -> list[str]:
        """The page's console so far (messages and exceptions), one string each."""
        out = []
        with self._cv:
            events = list(self.events)
        for e in events:
            p = e.get("params", {})
            if e.get("method") == "Runtime.consoleAPICalled":
                out.append(
                    f"{p['type']}: " + " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"])
                )
            elif e.get("method") == "Runtime.exceptionThrown":
                out.append(f"exception: {p['exceptionDetails'].get('text')}")
        return out

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=10)
        except (TimeoutError, RuntimeError, OSError):
            pass
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._cmd_w)


#: the viewer's state as base64 (the page's ``window._handle`` is the viewer's WebHandle)
VIEWER_STATE_JS = """(() => {
  const h = window._handle;
  if (!h) return null;
  const b = h.viewer_state();
  let s = "";
  for (const x of b) s += String.fromCharCode(x);
  return btoa(s);
})()"""


def look_at_page(url: str, tmp, *, wait_for: bytes) -> dict:
    """Open ``url`` in headless Chromium until the viewer's state holds ``wait_for`` (or
    :data:`PAGE_TIMEOUT_S` passes); the state, a screenshot and the console."""
    log = open(tmp / "chromium.log", "w")
    browser = DevTools(CHROMIUM, str(tmp / "profile"), log)
    seen: dict = {"state": b"", "png": None, "console": [], "seconds": None}
    t0 = time.monotonic()
    try:
        target = browser.call("Target.createTarget", url="about:blank")["targetId"]
        page = browser.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        browser.call("Runtime.enable", page)
        browser.call("Page.enable", page)
        browser.call("Page.navigate", page, url=url)
        while time.monotonic() - t0 < PAGE_TIMEOUT_S:
            got = browser.call("Runtime.evaluate", page, expression=VIEWER_STATE_JS, returnByValue=True)["result"]
            state = base64.b64decode(got["value"]) if got.get("value") else b""
            if wait_for in state and b"\n\x03\n\x01t" in state:  # the recording, and its timeline t
                seen["state"], seen["seconds"] = state, time.monotonic() - t0
                break
            time.sleep(0.5)
        if seen["seconds"] is not None:
            time.sleep(3.0)  # a few frames drawn with the data
            shot = browser.call("Page.captureScreenshot", page, format="png")
            seen["png"] = base64.b64decode(shot["data"])
            seen["state"] = base64.b64decode(
                browser.call("Runtime.evaluate", page, expression=VIEWER_STATE_JS, returnByValue=True)["result"][
                    "value"
                ]
            )
        seen["console"] = browser.console()
    finally:
        browser.close()
        log.close()
    return seen


@pytest.fixture(scope="module")
def pir(tmp_path_factory):
    root = tmp_path_factory.mktemp("pir")
    return get_scenario("pir14").write(
        root / "d", seed=5, duration=60.0, agents=None, drop=0.0, camera=False, params={"refractory": 4}
    )


# the live follow.rrd is read while it grows, without the footer a closed recording has
@pytest.mark.filterwarnings("ignore:RRD file has no footer")
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium (make browser-test installs Debian's chromium)")
def test_served_page_shows_the_stream_in_chromium(pir, tmp_path):
    out = tmp_path / "out"
    lines: list[str] = []
    seen: dict = {}
    now = [1000.0]

    def sleep(dt: float) -> None:  # a simulated clock; half-way, a browser looks at the page
        now[0] += dt
        if now[0] >= 1000.0 + 1.5 and not seen:
            url = next(ln.split("web viewer: ", 1)[1] for ln in lines if "web viewer: " in ln)
            recording = store_ids(out / "live" / "rrd" / "follow.rrd")[0][1]
            seen.update(look_at_page(url, tmp_path, wait_for=recording.encode()), url=url, recording=recording)

    follow(
        pir,
        out,
        trackers=("intruder",),
        options=FollowConfig(replay=20.0, poll=0.25),
        serve_web=WebServe(web_port=0, grpc_port=0),
        echo=lines.append,
        clock=lambda: now[0],
        sleep=sleep,
    )
    assert seen, "the follow ended before the browser looked"
    if seen["png"]:
        (tmp_path / "page.png").write_bytes(seen["png"])
    first_lines = [c.strip().splitlines()[0] if c.strip() else c for c in seen["console"]]
    renderer = [c for c in first_lines if "rasterizer" in c or "Renderer:" in c or "No available adapters" in c]
    trouble = sorted({c for c in first_lines if c.startswith(("error", "exception"))})
    why = f"renderer: {renderer[:3]}; console errors: {trouble[:5]}; screenshot: {tmp_path / 'page.png'}"
    assert seen["seconds"] is not None, f"the page never held recording {seen['recording']} ({seen['url']}); {why}"
    state = seen["state"]
    assert f"app_id=onebit&recording_id={seen['recording']}".encode() in state
    # the live blueprint the follow sent: its views, by name
    for view in (b"site: estimates as they are published", b"sensors: on / off"):
        assert view in state, f"view {view!r} not in the viewer's state; {why}"

    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(seen["png"])).convert("RGB")).astype(int)
    colours = len(np.unique(img.reshape(-1, 3), axis=0))
    assert colours > 50, f"a blank page: {colours} colours; {why}"
    rgb = np.array(tracker_color("intruder", rgb=LOOKS.get("intruder", Look()).rgb)[:3])
    # the newest estimate is a dot of radius 4 ui points: its inside is the colour, its rim blended
    estimate_pixels = int((np.abs(img - rgb).max(axis=2) <= 32).sum())
    assert estimate_pixels >= 8, f"no estimate drawn in the intruder's colour {tuple(int(v) for v in rgb)}; {why}"
