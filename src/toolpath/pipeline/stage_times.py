"""Run a command (``dvc repro``), pass its output through, and time every DVC stage it runs.

Run: python -m toolpath.pipeline.stage_times [--out reports/pipeline_time.json] -- dvc repro

DVC prints ``Running stage 'name':`` when a stage starts; a stage ends at the line its own process
prints last (:func:`end_line`, written when its MLflow run ends), else when the next stage starts or
the command ends.  A stage's time therefore includes its interpreter start-up and imports, the
overhead the pipeline's time budget is about, and equals the span of its MLflow run; DVC's own work
(before the first stage, hashing outputs and checking dependencies between stages) is counted apart.
Writes the seconds per stage, per stage family (``train@mcrl`` -> ``train``), DVC's and in all, and
exits with the command's own exit code.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path

STAGE = re.compile(r"Running stage '([^']+)'")
STAGE_END = re.compile(r"^toolpath: stage '([^']+)' (?:finished|failed)")


def started_at(pid: int) -> float | None:
    """When process ``pid`` started, in seconds on the clock ``time.time()`` reads (Linux), else None.
    Its age is exact to a clock tick (its start since boot against /proc/uptime); psutil's create_time
    adds that start to /proc/stat's boot time in whole seconds, up to 1 s off (0.35 s here), a tenth
    of a short stage."""
    try:
        ticks = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19])  # field 22, starttime
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return time.time() - (uptime - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return None


def end_line(stage: str, failed: bool, seconds: float, run_id: str) -> str:
    """The last line a stage's process prints (matched by :data:`STAGE_END`)."""
    return f"toolpath: stage '{stage}' {'failed' if failed else 'finished'} in {seconds:.1f} s (MLflow run {run_id})"


def stage_seconds(events: Iterable[tuple[float, str]], end: float) -> dict[str, float]:
    """Per stage, from (time, line) events: the time from its "Running stage" line to its own end line,
    else to the next stage's "Running stage" line (or ``end``)."""
    spans: list[list] = []  # [name, start, stop or None]
    for t, line in events:
        if m := STAGE.search(line):
            spans.append([m.group(1), t, None])
        elif (m := STAGE_END.search(line)) and spans and spans[-1][0] == m.group(1) and spans[-1][2] is None:
            spans[-1][2] = t
    bounds = [t for _, t, _ in spans[1:]] + [end]
    return {name: round((stop if stop is not None else bound) - start, 3)
            for (name, start, stop), bound in zip(spans, bounds, strict=True)}


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
              "families": by_family(seconds), "dvc_seconds": round(total - sum(seconds.values()), 3),
              "stages": seconds}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    families = ", ".join(f"{k} {v:.0f} s" for k, v in result["families"].items())
    print(f"{len(seconds)} stages in {total:.0f} s: {families}; DVC's own work {result['dvc_seconds']:.0f} s")
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
