"""The Rerun stream of ``onebit follow``: estimates as they are published, to a file and a viewer.

A live stream has one recording id (the follow run's), the same entity paths as the batch
recordings (``<tracker>/tracks/<track>``, ``sensors/<id>``, ``site/...``), and goes to an
``.rrd`` always -- written as it grows, so a crash leaves the data logged so far -- and,
when asked, to a viewer a user has open (``--connect``, a gRPC URL such as
``rerun+http://127.0.0.1:9876/proxy``) or to a web viewer this process serves
(``--serve-web``, :class:`WebServe`). Each publication is a handful of rows: they are sent
with ``send_columns`` (one call per track), never one ``log`` per row.

Serving takes two listening sockets: the stream (a Rerun gRPC server inside this process,
:class:`rerun.GrpcServerSink`, which takes the address to bind) and the page (HTML, JS and
wasm, served by the ``rerun`` CLI as a child process, ``rerun --serve-web --bind ADDR``:
the SDK's own :func:`rerun.serve_web_viewer` always binds every interface, 0.0.0.0, and
cannot be told otherwise). Both bind 127.0.0.1 unless ``--bind`` says otherwise.
"""

from __future__ import annotations

import errno
import ipaddress
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

import numpy as np
import polars as pl

from onebit.core.errors import ConfigError, OnebitError, bounded
from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz.frame import log_world_frame
from onebit.viz.inspect import rerun_binary
from onebit.viz.intruder import log_motion_states
from onebit.viz.recording import APPLICATION_ID, rerun_enabled
from onebit.viz.site import log_site

rr = lazy_module("rerun")
rrb = lazy_module("rerun.blueprint")

#: port of the web viewer page of ``--serve-web`` (Rerun's default)
WEB_PORT = 9090
#: port of the stream the page reads (Rerun's default gRPC port)
GRPC_PORT = 9876
#: where ``--serve-web`` listens unless ``--bind`` says otherwise: this machine only
LOCAL_BIND = "127.0.0.1"
#: seconds the page's server may take to listen before the follow gives up
WEB_START_TIMEOUT_S = 30.0
#: entity of the delay series, one Scalars per tracker: follow/delay/<tracker>
DELAY_ROOT = "follow/delay"


class PortInUseError(OnebitError):
    """A port ``--serve-web`` was told to listen on is taken (names the port and the flag)."""


@dataclass(frozen=True)
class WebServe:
    """Where ``--serve-web`` listens: the page (``web_port``) and the stream it reads
    (``grpc_port``), both on ``bind``. A port of 0 is a free one, chosen when serving starts."""

    #: address both servers bind: 127.0.0.1 (this machine only), 0.0.0.0 / :: (every interface) or one address
    bind: str = LOCAL_BIND
    #: port of the page (``--web-port``); 0 = a free one
    web_port: int = WEB_PORT
    #: port of the gRPC stream the page connects to (``--grpc-port``); 0 = a free one
    grpc_port: int = GRPC_PORT

    def __post_init__(self) -> None:
        for flag, port in (("--web-port", self.web_port), ("--grpc-port", self.grpc_port)):
            if not isinstance(port, int) or not 0 <= port <= 65535:
                raise ConfigError(f"{flag} {port!r}: expected a port in 0..65535 (0 = a free one)")
        try:
            ipaddress.ip_address(self.bind)
        except ValueError:
            raise ConfigError(
                f"--bind {self.bind!r}: expected an IP address (127.0.0.1 = this machine only, 0.0.0.0 = every interface)"
            ) from None
        if self.web_port and self.web_port == self.grpc_port:
            raise ConfigError(
                f"--web-port and --grpc-port are both {self.web_port}: the page and the stream need two ports"
            )

    @property
    def local_only(self) -> bool:
        """Whether only this machine can reach the servers (a loopback address)."""
        return ipaddress.ip_address(self.bind).is_loopback


@dataclass
class ServedViewer:
    """The web viewer of a follow: the page's URL, where it listens and the process serving it."""

    #: what a browser opens: the page, told which stream to read (``?url=``)
    url: str
    #: the stream the page reads (``rerun+http://HOST:PORT/proxy``)
    grpc_url: str
    #: the address, page port and stream port actually listened on
    bind: str
    web_port: int
    grpc_port: int
    #: the ``rerun --serve-web`` child serving the page
    process: subprocess.Popen

    def describe(self) -> list[str]:
        """Lines for the console: the URL, what listens where, and how to reach it privately."""
        where = f"{self.bind} ports {self.web_port} (page) and {self.grpc_port} (stream)"
        if ipaddress.ip_address(self.bind).is_loopback:
            reach = (
                f"this machine only; from another: ssh -L {self.web_port}:127.0.0.1:{self.web_port} "
                f"-L {self.grpc_port}:127.0.0.1:{self.grpc_port} THIS_HOST, then open the URL there"
            )
        else:
            reach = "reachable by ANY machine that can reach this one: a live view of who is where, without a password"
        return [f"web viewer: {self.url}", f"  listening on {where}: {reach}"]

    def stop(self) -> None:
        """End the page's server (the child this process started), waiting for it."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def listen_port(bind: str, port: int, flag: str) -> int:
    """``port`` if nothing listens on it at ``bind`` (0: a free port, chosen by the system).

    Raises :class:`PortInUseError` naming the port and ``flag`` when it is taken.
    A probe, not a reservation: the server binds it right after.
    """
    family = socket.AF_INET6 if ipaddress.ip_address(bind).version == 6 else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the servers do: TIME_WAIT is no conflict
        try:
            probe.bind((bind, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise PortInUseError(_in_use(bind, port, flag)) from None
            raise ConfigError(f"--bind {bind} {flag} {port}: cannot listen there ({exc.strerror})") from None
        return probe.getsockname()[1]


def check_ports(serve: WebServe) -> None:
    """Raise :class:`PortInUseError` now if a port ``serve`` names is taken (before a follow
    replaces ``OUT/live``); free ports (0) are chosen later, when serving starts."""
    for flag, port in (("--grpc-port", serve.grpc_port), ("--web-port", serve.web_port)):
        if port:
            listen_port(serve.bind, port, flag)


def _in_use(bind: str, port: int, flag: str) -> str:
    return (
        f"{flag} {port}: port {port} is already in use on {bind} (another follow --serve-web, or a Rerun "
        f"viewer?); choose another with {flag} N, or {flag} 0 for a free one"
    )


def _url_host(bind: str) -> str:
    """The host a browser uses for servers bound to ``bind``."""
    ip = ipaddress.ip_address(bind)
    if ip.is_loopback:
        return bind if ip.version == 4 else f"[{bind}]"
    if ip.is_unspecified:
        return socket.gethostname()
    return bind if ip.version == 4 else f"[{bind}]"


def _web_viewer_command() -> list[str]:
    """The ``rerun`` binary itself (not the Python wrapper in ``bin/``, which would outlive a
    terminate: it runs the binary as its own child)."""
    import importlib.util

    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin:
        binary = Path(spec.origin).parent / "rerun"
        if binary.is_file():
            return [str(binary)]
    return [str(rerun_binary())]


def _death_signal():
    """A function for the child to call between fork and exec (``preexec_fn``) so that the
    page's server ends when this process does, even on ``kill -9`` (Linux ``prctl``
    ``PR_SET_PDEATHSIG``); ``None`` elsewhere. Resolved here, in the parent: the child, forked
    from a process with Rerun's threads running, only makes the one call."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    args = (ctypes.c_int(1), ctypes.c_ulong(signal.SIGTERM))  # PR_SET_PDEATHSIG, SIGTERM
    return lambda: prctl(*args)


def _wait_listening(host: str, port: int, *, proc: subprocess.Popen | None = None) -> bool:
    """Whether ``host:port`` accepts a connection within :data:`WEB_START_TIMEOUT_S` (sooner
    ``False`` when ``proc``, the server, ends first)."""
    deadline = time.monotonic() + WEB_START_TIMEOUT_S
    while time.monotonic() < deadline and (proc is None or proc.poll() is None):
        try:
            socket.create_connection((host, port), timeout=0.5).close()
            return True
        except OSError:
            time.sleep(0.05)
    return False


def _dial_host(bind: str) -> str:
    """Where this process reaches a server bound to ``bind``."""
    return "127.0.0.1" if ipaddress.ip_address(bind).is_unspecified else bind


def start_web_viewer(bind: str, port: int, grpc_url: str, *, log: Path) -> subprocess.Popen:
    """Serve the page on ``bind:port`` (``rerun --serve-web --bind``), pointed at ``grpc_url``.

    Returns the child once it accepts connections; its output goes to ``log``. Raises
    :class:`PortInUseError` when the port was taken meanwhile, :class:`OnebitError` when it
    does not start.
    """
    cmd = [*_web_viewer_command(), "--serve-web", "--bind", bind, "--web-viewer-port", str(port), grpc_url]
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=subprocess.STDOUT,
            preexec_fn=_death_signal(),  # noqa: PLW1509 - one prctl call, resolved in the parent
        )
    if _wait_listening(_dial_host(bind), port, proc=proc):
        return proc
    said = Path(log).read_text(errors="replace")
    if proc.poll() is None:
        proc.kill()
    proc.wait()
    if "Address already in use" in said:
        raise PortInUseError(_in_use(bind, port, "--web-port"))
    last = said.strip().splitlines()[-1] if said.strip() else "no output"
    raise OnebitError(
        f"--serve-web: the web viewer ({cmd[0]}) did not listen on port {port}: {bounded(last)} (see {log})"
    )


def open_live(
    path: str | Path,
    *,
    recording_id: str,
    connect: str | None = None,
    serve_web: WebServe | None = None,
) -> tuple[rr.RecordingStream, ServedViewer | None]:
    """A recording stream writing ``path`` as it grows, plus a viewer connection if asked.

    With ``serve_web``, also the web viewer (:class:`ServedViewer`; :func:`close_live` stops
    it), its output in ``web-viewer.log`` next to ``path``. Ports are checked before anything
    listens: a taken one raises :class:`PortInUseError` naming it and its flag.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if serve_web is not None:
        bind = serve_web.bind
        grpc_port = listen_port(bind, serve_web.grpc_port, "--grpc-port")
        web_port = listen_port(bind, serve_web.web_port, "--web-port")
        if web_port == grpc_port:  # both free ports: the system may hand out the same one twice
            web_port = listen_port(bind, 0, "--web-port")
    with rerun_enabled():
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
        sinks = [rr.FileSink(str(path))]
        if connect:
            sinks.append(rr.GrpcSink(connect))
        if serve_web is not None:
            # Rerun's gRPC server answers pages from localhost origins; an exposed one, its own page too
            origins = None if serve_web.local_only else [f"http://*:{web_port}"]
            sinks.append(rr.GrpcServerSink(bind, grpc_port, cors_allow_origin=origins))
        rec.set_sinks(*sinks)
    if serve_web is None:
        return rec, None
    grpc_url = f"rerun+http://{_url_host(bind)}:{grpc_port}/proxy"
    try:
        if not _wait_listening(_dial_host(bind), grpc_port):  # the server logs a bind failure, never raises it
            raise PortInUseError(_in_use(bind, grpc_port, "--grpc-port"))
        proc = start_web_viewer(bind, web_port, grpc_url, log=path.parent / "web-viewer.log")
    except BaseException:
        rec.disconnect()
        raise
    url = f"http://{_url_host(bind)}:{web_port}/?url={quote(grpc_url, safe='')}"
    return rec, ServedViewer(url, grpc_url, bind, web_port, grpc_port, proc)


def log_live_site(rec: rr.RecordingStream, site, region_graph) -> None:
    """The site once (static), as in every stage recording."""
    log_site(rec, site, region_graph)


def log_states(rec: rr.RecordingStream, edges: pl.DataFrame) -> None:
    """New accepted toggle edges (``t``, ``sensor``, ``on``) on ``sensors/<id>`` as on / off
    state changes, styled as in the batch recordings (:func:`onebit.viz.intruder.log_motion_states`)."""
    if edges is None or edges.height == 0:
        return
    log_motion_states(rec, edges, sorted(edges["sensor"].unique().to_list()))


def live_blueprint(trackers: list[str]) -> rrb.Blueprint:
    """The stream's layout: the site with the estimates as published, the sensors' states and
    the publication delay of every tracker on one plot."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(
                name="site: estimates as they are published",
                origin="/",
                contents=["+ site/**", *[f"+ {paths.tracker_root(t)}/**" for t in trackers]],
            ),
            rrb.Vertical(
                rrb.StateTimelineView(name="sensors: on / off", origin="/", contents=["+ sensors/**"]),
                rrb.TimeSeriesView(
                    name="publication delay (s, wall clock)", origin="/", contents=[f"+ {DELAY_ROOT}/**"]
                ),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def log_estimates(
    rec: rr.RecordingStream, tracker: str, rows: pl.DataFrame, *, rgb: tuple[int, int, int] | None = None
) -> None:
    """Newly published track rows (``track``, ``t``, ``x``, ``y``) as points on
    ``<tracker>/tracks/<track>`` in the tracker's colour ``rgb``; rows without a position are skipped."""
    if rows is None or rows.height == 0 or "x" not in rows.columns:
        return
    rows = rows.drop_nulls(["t", "x", "y"])
    if rows.height == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    color = colors.tracker_color(tracker, rgb=rgb)
    for (track,), g in rows.sort("t").group_by("track", maintain_order=True):
        xy = g.select("x", "y").to_numpy().astype(np.float64)
        rec.send_columns(
            paths.track(tracker, str(track)),
            indexes=[paths.time_column(g["t"].to_numpy())],
            columns=rr.Points2D.columns(positions=xy, colors=[color] * len(xy), radii=[-4.0] * len(xy)),
        )


def log_delays(rec: rr.RecordingStream, tracker: str, t: np.ndarray, delay_s: np.ndarray) -> None:
    """The publication delay (s) of each estimate on ``follow/delay/<tracker>`` over ``t``."""
    if len(t) == 0:
        return
    rec.send_columns(
        f"{DELAY_ROOT}/{paths.part(tracker)}",
        indexes=[paths.time_column(t)],
        columns=rr.Scalars.columns(scalars=np.asarray(delay_s, dtype=np.float64)),
    )


def send_live_blueprint(rec: rr.RecordingStream, trackers: list[str]) -> None:
    """Send :func:`live_blueprint` with the stream (the viewer opens on it)."""
    rec.send_blueprint(live_blueprint(trackers), make_active=True, make_default=True)


def close_live(rec: rr.RecordingStream, served: ServedViewer | None = None) -> None:
    """Flush and close every sink, and stop the web viewer if one is served."""
    try:
        rec.flush()
        rec.disconnect()
    finally:
        if served is not None:
            served.stop()
