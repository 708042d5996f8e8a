"""``onebit snapshot RUN --at T [T...] [--view NAME] --out DIR``: a run's recordings rendered
headless to PNGs in Rerun's own viewer, as a user opening the run would see them.

The viewer (the ``rerun`` binary of the installed ``rerun-sdk``) is started headless on a free
port, opens ``RUN/rrd/*.rrd`` and ``RUN/rrd/blueprint.rbl``, waits until everything is loaded,
selects the tab named ``NAME`` (the layout's :func:`onebit.viz.blueprint.save_run_blueprint`
tabs: a tab whose name is ``NAME`` or starts with it, case ignored), then for each time ``T``
(seconds on the timeline ``t``) pauses there and saves ``DIR/<tab>-t<T>.png``.

Rendering needs a Vulkan driver. A machine without a GPU renders in software with Mesa's
lavapipe (Debian/Ubuntu package ``mesa-vulkan-drivers``); :func:`vulkan_problem` says what is
missing before the viewer is started, and :class:`RenderError` carries the instructions.
"""

from __future__ import annotations

import glob
import json
import os
import re
import socket
import sys
import time
from pathlib import Path

from onebit.core.errors import InputError, OnebitError

#: Where the Vulkan loader looks for drivers (ICD manifests), besides ``VK_ICD_FILENAMES``.
ICD_DIRS = ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d")
#: Seconds to wait for the viewer to load the recordings.
LOAD_TIMEOUT_S = 120.0
#: Seconds the viewer is given to paint after the time cursor moves.
SETTLE_S = 3.0

INSTALL_HELP = (
    "Rerun's viewer renders with Vulkan; for software rendering (no GPU needed) install Mesa's "
    "Vulkan drivers: 'sudo apt-get install mesa-vulkan-drivers' (Debian, Ubuntu), "
    "'sudo dnf install mesa-vulkan-drivers' (Fedora), 'sudo pacman -S vulkan-swrast' (Arch); "
    "on macOS and Windows the system driver is used. Or set VK_ICD_FILENAMES to a driver's ICD json."
)


class RenderError(OnebitError):
    """The recordings cannot be rendered here (no Vulkan driver, the viewer failed)."""


def vulkan_problem() -> str | None:
    """Why Rerun's viewer cannot render on this machine, with what to install, or ``None``.

    Only Linux is checked (ICD manifests in :data:`ICD_DIRS` or ``VK_ICD_FILENAMES``); other
    systems bring their driver."""
    if not sys.platform.startswith("linux"):
        return None
    env = os.environ.get("VK_ICD_FILENAMES") or os.environ.get("VK_DRIVER_FILES")
    if env:
        files = [f for f in env.split(os.pathsep) if f]
        if any(Path(f).is_file() for f in files):
            return None
        return f"VK_ICD_FILENAMES names no existing file ({env}). {INSTALL_HELP}"
    if any(glob.glob(os.path.join(d, "*.json")) for d in ICD_DIRS):
        return None
    return f"no Vulkan driver found (no ICD json in {', '.join(ICD_DIRS)}). {INSTALL_HELP}"


def run_recordings(run: str | Path) -> list[Path]:
    """The files of a run the viewer opens: ``rrd/*.rrd`` and ``rrd/*.rbl``."""
    rrd = Path(run) / "rrd"
    files = sorted(rrd.glob("*.rrd")) + sorted(rrd.glob("*.rbl"))
    if not any(f.suffix == ".rrd" for f in files):
        raise InputError("no Rerun recordings (rrd/*.rrd): run 'onebit run' without --no-rrd", file=str(rrd))
    return [f.resolve() for f in files]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _viewer_binary() -> str | None:
    import rerun

    exe = Path(rerun.__file__).parent.parent / "rerun_cli" / "rerun"
    return str(exe) if exe.exists() else None


def tabs(blueprint: dict) -> dict[str, str]:
    """``{tab name: container path}`` of the layout's top ``Tabs`` container (a blueprint
    as :meth:`rerun.experimental.ViewerClient.get_blueprint` reads it)."""
    out: dict[str, str] = {}
    for cont in blueprint.values():
        c = cont.get("ContainerBlueprint") if isinstance(cont, dict) else None
        if not c or c.get("container_kind") != "Tabs":
            continue
        for child in c.get("contents", []):
            entry = blueprint.get("/" + child, {})
            name = (entry.get("ContainerBlueprint") or entry.get("ViewBlueprint") or {}).get("display_name", child)
            out.setdefault(name, child)
    return out


def choose_tab(names: list[str], wanted: str) -> str:
    """The tab called ``wanted`` (exactly, else the one whose name starts with it, case
    ignored); an :class:`InputError` listing the tabs when none or several fit."""
    low = wanted.strip().lower()
    exact = [n for n in names if n.lower() == low]
    if exact:
        return exact[0]
    starts = [n for n in names if n.lower().startswith(low)]
    if len(starts) == 1:
        return starts[0]
    what = "several tabs start with it" if starts else "no such tab"
    raise InputError(f"--view {wanted!r}: {what}; the run's tabs are: {', '.join(repr(n) for n in names) or 'none'}")


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", name).strip("-").lower() or "view"


def snapshot(
    run: str | Path,
    times: list[float],
    out: str | Path,
    *,
    view: str | None = None,
    echo=print,
) -> list[Path]:
    """Render the run's recordings at ``times`` (s on ``t``) to PNGs in ``out`` (module
    docstring); the tab ``view`` (``None``: the one the layout opens on). Returns the files."""
    files = run_recordings(run)
    problem = vulkan_problem()
    if problem is not None:
        raise RenderError(problem)
    from rerun.experimental import ViewerClient

    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    exe = _viewer_binary()
    os.environ.setdefault("RUST_LOG", "error")  # the viewer's own log lines: errors only
    try:
        viewer = ViewerClient.spawn(
            headless=True,
            port=_free_port(),
            hide_welcome_screen=True,
            **({"executable_path": exe} if exe else {}),
        )
    except Exception as exc:  # the binary missing or refusing to start
        raise RenderError(f"could not start Rerun's viewer: {exc}. {INSTALL_HELP}") from None
    written: list[Path] = []
    try:
        try:
            viewer.open([str(f) for f in files])
            _wait_loaded(viewer)
        except RenderError:
            raise
        except Exception as exc:  # a viewer that died on start: no graphics adapter, most often
            raise RenderError(f"Rerun's viewer failed ({type(exc).__name__}: {exc}). {INSTALL_HELP}") from None
        name = _select_tab(viewer, view)
        stem = _slug(name) if name else "run"
        for t in times:
            viewer.set_time("t", duration=float(t), play_state="paused")
            time.sleep(SETTLE_S)
            path = out / f"{stem}-t{t:g}.png"
            tmp = path.with_name(path.name + ".tmp.png")
            viewer.save_screenshot(str(tmp))
            os.replace(tmp, path)
            written.append(path)
            echo(f"wrote {path}")
    finally:
        try:
            viewer.quit()
        except Exception:  # already gone: nothing to stop
            pass
    return written


def _wait_loaded(viewer) -> None:
    """Wait until the viewer has every recording loaded with its timeline ``t``."""
    end = time.monotonic() + LOAD_TIMEOUT_S
    while True:
        state = viewer.get_state()
        ready = state.recordings and all(r.timelines for r in state.recordings)
        if not state.loading and ready:
            time.sleep(1.0)  # the layout arrives with the recordings; let it apply
            return
        if time.monotonic() > end:
            raise RenderError(f"the viewer had not loaded the recordings after {LOAD_TIMEOUT_S:g} s")
        time.sleep(0.5)


def _select_tab(viewer, view: str | None) -> str | None:
    """Make the tab ``view`` the active one (its name), or say which tab is shown (``None``
    when the layout has no tabs)."""
    rec = viewer.get_state().recordings[0]  # one run: one recording id shared by every stage
    viewer.set_location(rec.location)  # show the recording (the viewer may open on its catalog table)
    end = time.monotonic() + 20.0
    while True:  # the run's layout replaces the viewer's default one shortly after loading
        blueprint = viewer.get_blueprint(store_id=rec.store_id).blueprint
        found = tabs(blueprint)
        if found or time.monotonic() > end:
            break
        time.sleep(0.5)
    if not found:
        if view is not None:
            raise InputError(f"--view {view!r}: the run's layout has no tabs")
        return None
    holder = next(
        k
        for k, v in blueprint.items()
        if isinstance(v, dict) and (v.get("ContainerBlueprint") or {}).get("container_kind") == "Tabs"
    )
    if view is None:
        active = blueprint[holder]["ContainerBlueprint"].get("active_tab")
        return next((n for n, c in found.items() if c == active), next(iter(found)))
    name = choose_tab(list(found), view)
    blueprint = json.loads(json.dumps(blueprint))
    blueprint[holder]["ContainerBlueprint"]["active_tab"] = found[name]
    viewer.set_blueprint(blueprint, store_id=rec.store_id)
    time.sleep(1.0)
    return name
