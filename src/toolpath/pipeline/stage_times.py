"""Run a command (``dvc repro``), pass its output through, and time every DVC stage it runs.

Run: python -m toolpath.pipeline.stage_times [--out reports/pipeline_time.json] -- dvc repro

DVC prints ``Running stage 'name':`` when a stage starts; a stage ends when the next one starts or
the command ends.  Each stage's wall time therefore includes its interpreter start-up and imports,
which is the overhead the pipeline's time budget is about.  Writes the seconds per stage, per stage
family (``train@gear`` -> ``train``) and in all, and exits with the command's own exit code.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path

STAGE = re.compile(r"Running stage '([^']+)'")


def stage_seconds(events: Iterable[tuple[float, str]], end: float) -> dict[str, float]:
    """Per stage, from (time, line) events: the time from its "Running stage" line to the next one's
    (or ``end``)."""
    starts = [(t, m.group(1)) for t, line in events if (m := STAGE.search(line))]
    bounds = [t for t, _ in starts[1:]] + [end]
    return {name: round(stop - start, 3) for (start, name), stop in zip(starts, bounds, strict=True)}


def by_family(seconds: dict[str, float]) -> dict[str, float]:
    """Stage seconds summed per family: the name before ``@``."""
    families: dict[str, float] = {}
    for name, value in seconds.items():
        family = name.split("@")[0]
        families[family] = round(families.get(family, 0.0) + value, 3)
    return families


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    # outside reports/timing: the report stage depends on that folder, and this file is written after it
    parser.add_argument("--out", type=Path, default=Path("reports/pipeline_time.json"))
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("no command given (put it after --)")
    started = time.monotonic()
    events: list[tuple[float, str]] = []
    try:
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    except OSError as exc:  # not found, not executable: say so, write nothing
        print(f"error: cannot run {command[0]!r}: {exc.strerror or exc}", file=sys.stderr)
        return 127
    with proc:
        for line in proc.stdout:  # type: ignore[union-attr]
            events.append((time.monotonic() - started, line))
            sys.stdout.write(line)
            sys.stdout.flush()
    total = time.monotonic() - started
    seconds = stage_seconds(events, total)
    result = {"command": " ".join(command), "exit_code": proc.returncode, "total_seconds": round(total, 3),
              "families": by_family(seconds), "stages": seconds}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    families = ", ".join(f"{k} {v:.0f} s" for k, v in result["families"].items())
    print(f"{len(seconds)} stages in {total:.0f} s: {families}")
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
