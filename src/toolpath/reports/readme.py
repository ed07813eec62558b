"""Put the measured figures into README.md.  Run: python -m toolpath.reports.readme (``make readme``)

Three blocks of README.md are generated, never typed: ``report`` (the report stage's summary,
``reports/readme_block.md``, a DVC output), ``time`` (the pipeline's measured time,
``reports/pipeline_time.json``, written by ``make repro``) and ``bench`` (the G-code and ``toolpath smooth``
speed figures, ``reports/bench/gcode.json``, written by ``make bench``).  This command, run on purpose,
replaces each block between its markers (the report's always; the others where README.md has their
markers, so a README of another layout keeps working); README.md is no DVC output, so no stage writes it.
``tests/test_docs.py`` fails when a block differs from what its file gives.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from pathlib import Path

from toolpath.reports.document import replace_block

#: block -> (its source under the repository root, what writes the source)
SOURCES = {"report": ("reports/readme_block.md", "the report stage: run `make repro`"),
           "time": ("reports/pipeline_time.json", "`make repro`"),
           "bench": ("reports/bench/gcode.json", "`make bench`")}


def _k(lines_per_s: float) -> str:
    """Lines per second as the README says them: 1.46 M, 376 k, 4.6 k."""
    if lines_per_s >= 1e6:
        return f"{lines_per_s / 1e6:.2f} M"
    return f"{lines_per_s / 1e3:.1f} k" if lines_per_s < 1e4 else f"{lines_per_s / 1e3:.0f} k"


def time_block(timing: Mapping, stages: tuple[str, ...] = ()) -> str:
    """The default profile's measured time, by stage family, from ``reports/pipeline_time.json``;
    ``stages``: every stage family of ``dvc.yaml``, so that families DVC found up to date (and did not
    re-run: their committed metrics and their inputs unchanged) are named, not silently left out."""
    families = sorted(timing["families"].items(), key=lambda kv: -kv[1])
    total = timing["total_seconds"]
    if timing.get("exit_code", 0):  # a run that stopped is no measure of the whole pipeline: say so
        last = list(timing.get("stages") or {"?": 0})[-1]
        return (f"The last measured `dvc repro` of the default profile stopped with exit code {timing['exit_code']} "
                f"in stage `{last}` after {total / 60:.1f} minutes ({total:.0f} s; by stage family: "
                f"{', '.join(f'{name} {seconds:.0f} s' for name, seconds in families)}); see "
                "`reports/pipeline_time.json`.")
    dvc = (f", DVC's own work between stages {timing['dvc_seconds']:.0f} s" if "dvc_seconds" in timing else "")
    skipped = [name for name in stages if name not in timing["families"]]
    up_to_date = (f" {_names(skipped)} {'was' if len(skipped) == 1 else 'were'} up to date (inputs unchanged since "
                  "the committed results) and did not re-run, so they are not in this figure." if skipped else "")
    return (f"The last measured `dvc repro` of the default profile took {total / 60:.1f} minutes ({total:.0f} s; "
            f"by stage family: {', '.join(f'{name} {seconds:.0f} s' for name, seconds in families)}{dvc}); "
            "`make repro` adds the install before it (once per fresh clone) and writes these seconds per stage to "
            f"`reports/pipeline_time.json`.{up_to_date}")


def _names(items: list[str]) -> str:
    quoted = [f"`{item}`" for item in items]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " and " + quoted[-1]


def bench_block(bench: Mapping) -> str:
    """The G-code reading and ``toolpath smooth`` speeds of ``reports/bench/gcode.json``."""
    readers, smooth = bench["readers"], bench["smooth"]
    ours = readers["toolpath.gcode"]
    rough, ratio = smooth["dispatch, rough"], bench["ratio_ours_to"]
    first_run = rough["lines"] / rough["runs"][0]
    return (
        f"Measured by `make bench` (`reports/bench/gcode.json`, medians of {len(ours['runs'])} runs in one process "
        f"each): reading a {bench['file']['lines']:,}-line G01 program at {_k(ours['lines_per_s'])} lines/s "
        f"(gcodeparser {_k(readers['gcodeparser']['lines_per_s'])}, pygcode {_k(readers['pygcode']['lines_per_s'])}, "
        f"on the same file: {ratio['gcodeparser']:.0f}x and {ratio['pygcode']:.0f}x); "
        f"`toolpath smooth` at {_k(smooth['mean, clean']['lines_per_s'])} lines/s on a "
        f"{smooth['mean, clean']['lines'] / 1e6:.0f} M-line program whose windows are smooth already "
        f"({_k(smooth['mean, clean, 10M lines']['lines_per_s'])} on "
        f"{smooth['mean, clean, 10M lines']['lines'] / 1e6:.0f} M lines, peak "
        f"{smooth['mean, clean, 10M lines']['peak_rss_mb']:.0f} MB); on a {rough['lines'] / 1e3:.0f} k-line program "
        f"where {rough['spikes']:.0%} of the points are spikes (each smoothed stretch measured exactly both ways), "
        f"{_k(smooth['mean, rough']['lines_per_s'])} lines/s with `--method mean` and {_k(rough['lines_per_s'])} "
        f"lines/s with the default dispatch (NACOA is most of the difference; the first run of a process, which also "
        f"pays its imports, {_k(first_run)}); {_k(smooth['mean, clean, --report']['lines_per_s'])} lines/s with "
        "`--report`, which also plans the machining time of every feed run. This machine's speed varies by up to a "
        "third from run to run; the file keeps each run.")


def blocks(root: Path, names: tuple[str, ...] = tuple(SOURCES)) -> dict[str, str]:
    """Each generated block of ``names`` from its source file under ``root``; a missing source raises
    FileNotFoundError."""
    makers = {"report": lambda text: text, "time": lambda text: time_block(json.loads(text), _stage_families(root)),
              "bench": lambda text: bench_block(json.loads(text))}
    return {name: makers[name]((root / SOURCES[name][0]).read_text(encoding="utf-8")) for name in names}


def _stage_families(root: Path) -> tuple[str, ...]:
    """The stage names of ``root/dvc.yaml`` (a matrix stage is one family); none without the file."""
    import yaml

    path = root / "dvc.yaml"
    return tuple(yaml.safe_load(path.read_text(encoding="utf-8")).get("stages", {})) if path.exists() else ()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--root", type=Path, default=Path("."), help="the repository (default: here)")
    parser.add_argument("--readme", type=Path, default=Path("README.md"))
    args = parser.parse_args(argv)
    try:
        text = args.readme.read_text(encoding="utf-8")
        # the report's block is every README's; the time and bench blocks where the README has their markers
        names = tuple(n for n in SOURCES if n == "report" or f"<!-- {n}:begin" in text)
        for name, block in blocks(args.root, names).items():
            text = replace_block(text, block, str(args.readme), name)
        args.readme.write_text(text, encoding="utf-8")
    except FileNotFoundError as exc:
        made_by = {str(args.root / path): who for path, who in SOURCES.values()}
        hint = f" ({made_by[exc.filename]} writes it)" if exc.filename in made_by else ""
        print(f"{exc.filename}: not found{hint}", file=sys.stderr)
        return 2
    except (OSError, ValueError, KeyError) as exc:
        print(f"{args.readme}: cannot write the measured figures ({type(exc).__name__}: {exc})", file=sys.stderr)
        return 2
    print(f"wrote the {', '.join(names)} block(s) into {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
