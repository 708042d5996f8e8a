"""Write ``docs/parameters.md`` from the config declarations (:mod:`onebit.core.params`, through
:func:`onebit.pipeline.config_show.reference_markdown`).

    python tools/params_md.py            # (re)write docs/parameters.md
    python tools/params_md.py --check    # exit 1 if docs/parameters.md is not what it would write
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from tools.generated import write_or_check  # noqa: E402 -- the checkout's tools, beside this file

OUT = ROOT / "docs" / "parameters.md"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--check", action="store_true", help="only say whether docs/parameters.md is current (exit 1 if not)"
    )
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    from onebit.pipeline.config_show import reference_markdown  # noqa: PLC0415 -- the checkout's own package

    text = reference_markdown()
    return write_or_check(text, args.out, check=args.check, tool="tools/params_md.py")


if __name__ == "__main__":
    sys.exit(main())
