"""Every command block of a tutorial (a ```console fence in docs/tutorials/*.md) runs, in
order, in an empty folder, as the tutorial says: a tutorial that stops working fails here.

``onebit`` on the tutorial's PATH is this checkout's ``onebit.cli.main`` in a fresh process
forked from a server that imported the CLI once (a dozen commands would otherwise pay the
import, 1.5 s of CPU each); the command gets the shell's arguments, folder, environment,
standard streams and exit status, as the installed entry point would."""

from __future__ import annotations

import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = sorted(p for p in (ROOT / "docs" / "tutorials").glob("*.md") if p.name != "index.md")
BLOCK = re.compile(r"^```console\n(.*?)^```", re.S | re.M)


def blocks(path: Path) -> list[str]:
    return BLOCK.findall(path.read_text())


def test_every_tutorial_has_commands_and_is_listed():
    assert {p.stem for p in TUTORIALS} >= {"beams", "motion", "frames", "casas", "ceiling"}
    index = (ROOT / "docs" / "tutorials" / "index.md").read_text()
    readme = (ROOT / "README.md").read_text()
    for p in TUTORIALS:
        assert blocks(p), f"{p.name}: no ```console block"
        assert f"({p.name})" in index and f"(docs/tutorials/{p.name})" in readme, p.name


SERVER = textwrap.dedent(
    """
    import atexit, json, os, signal, socket, sys, traceback
    from onebit.cli import main
    # what the commands import on first use, imported here once (every fork would import it again)
    import networkx, PIL.Image, pyarrow, rerun, scipy.optimize, scipy.spatial

    listener = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    listener.bind(sys.argv[1])
    listener.listen()

    def reap(*_):
        try:
            while os.waitpid(-1, os.WNOHANG)[0]:
                pass
        except ChildProcessError:
            pass

    signal.signal(signal.SIGCHLD, reap)
    print("ready", flush=True)
    while True:
        conn, _ = listener.accept()
        if os.fork():
            conn.close()
            continue
        listener.close()
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        msg, fds, _, _ = socket.recv_fds(conn, 1 << 20, 3)
        req = json.loads(msg)
        for i, fd in enumerate(fds):  # the caller's stdin, stdout, stderr
            os.dup2(fd, i)
            os.close(fd)
        os.chdir(req["cwd"])
        os.environ.clear()
        os.environ.update(req["env"])
        sys.argv = ["onebit", *req["argv"]]
        try:
            code = main(req["argv"])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (exc.code is not None)
            if isinstance(exc.code, str):
                print(exc.code, file=sys.stderr)
        except BaseException:
            traceback.print_exc()
            code = 1
        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
        conn.send(str(int(code)).encode())
        os._exit(int(code))
    """
)

CLIENT = textwrap.dedent(
    """
    import json, os, socket, sys
    s = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    s.connect(sys.argv[1])
    req = {"argv": sys.argv[2:], "cwd": os.getcwd(), "env": dict(os.environ)}
    socket.send_fds(s, [json.dumps(req).encode()], [0, 1, 2])
    status = s.recv(16)
    if not status:
        sys.exit("onebit (test shim): the command's process died without an exit status")
    sys.exit(int(status))
    """
)


@pytest.fixture(scope="module")
def onebit_bin(tmp_path_factory):
    """A folder holding ``onebit`` (module docstring), with its server running."""
    root = tmp_path_factory.mktemp("bin")
    sock_dir = Path(tempfile.mkdtemp(prefix="onebit-"))  # a short path: a socket's is at most 107 bytes
    sock = sock_dir / "s"
    env = dict(os.environ, RERUN_ANALYTICS="0")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    server = subprocess.Popen(
        [sys.executable, "-c", SERVER, str(sock)], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, env=env
    )
    try:
        assert server.stdout.readline() == b"ready\n", "the onebit server did not start"
        (root / "client.py").write_text(CLIENT)
        shim = root / "onebit"
        shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -I -S "{root / "client.py"}" "{sock}" "$@"\n')
        shim.chmod(shim.stat().st_mode | stat.S_IXUSR)
        yield root
    finally:
        server.kill()
        server.wait()
        server.stdout.close()
        shutil.rmtree(sock_dir, ignore_errors=True)


@pytest.mark.parametrize("tutorial", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_commands_run(tutorial, tmp_path, onebit_bin):
    bin_dir = onebit_bin  # `onebit` as the tutorial types it, this checkout's code
    work = tmp_path / "work"
    work.mkdir()
    script = "set -euo pipefail\n" + "\n".join(blocks(tutorial))
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", RERUN_ANALYTICS="0")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(["bash", "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (
        f"{tutorial.name}: exit {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
