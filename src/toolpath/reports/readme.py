"""Put the report's summary block into README.md.  Run: python -m toolpath.reports.readme (``make readme``)

The report stage writes the block (``<paths.report>/readme_block.md``, a DVC output); this command,
run on purpose, replaces the part of README.md between the report markers with it.  README.md is no
DVC output, so no stage writes it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toolpath.reports.document import replace_block


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--block", type=Path, default=Path("reports/readme_block.md"),
                        help="the block the report stage wrote (default: %(default)s)")
    parser.add_argument("--readme", type=Path, default=Path("README.md"))
    args = parser.parse_args(argv)
    try:
        block = args.block.read_text(encoding="utf-8")
        args.readme.write_text(replace_block(args.readme.read_text(encoding="utf-8"), block, str(args.readme)),
                               encoding="utf-8")
    except FileNotFoundError as exc:
        hint = " (the report stage writes it: run `make repro`)" if Path(exc.filename) == args.block else ""
        print(f"{exc.filename}: not found{hint}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as exc:
        print(f"{args.readme}: cannot write the report summary ({exc})", file=sys.stderr)
        return 2
    print(f"wrote the report block into {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
