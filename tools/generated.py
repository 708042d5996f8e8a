"""The one step of every tool that writes a generated page: write it atomically, or with
``--check`` only say whether the page on disk is what the tool would write. Standard library only."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path


def write_or_check(text: str, out: Path, *, check: bool, tool: str) -> int:
    """Write ``text`` to ``out`` atomically (0), or with ``check`` compare it with ``out``: 0 when
    equal, else 1 with a line naming ``tool`` to run."""
    if check:
        current = out.read_text(encoding="utf-8") if out.exists() else ""
        if current != text:
            print(f"{out} is not current: run python {tool}", file=sys.stderr)
            return 1
        return 0
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.stem}-", suffix=out.suffix)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, out)
    print(f"wrote {out}")
    return 0
