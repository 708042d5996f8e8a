"""Write ``docs/parameters.md`` from the config declarations (:mod:`onebit.core.params`, through
:func:`onebit.pipeline.config_show.reference_markdown`).

    python tools/params_md.py            # (re)write docs/parameters.md
    python tools/params_md.py --check    # exit 1 if docs/parameters.md is not what it would write
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "parameters.md"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--check", action="store_true", help="only say whether docs/parameters.md is current (exit 1 if not)"
    )
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from onebit.pipeline.config_show import reference_markdown  # noqa: PLC0415 -- the checkout's own package

    text = reference_markdown()
    if args.check:
        current = args.out.read_text(encoding="utf-8") if args.out.exists() else ""
        if current != text:
            print(f"{args.out} is not current: run python tools/params_md.py", file=sys.stderr)
            return 1
        return 0
    fd, tmp = tempfile.mkstemp(dir=args.out.parent, prefix=".parameters-", suffix=".md")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
