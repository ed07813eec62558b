"""G-code reading and ``toolpath smooth`` throughput, beside ``gcodeparser`` and ``pygcode`` on the same file.

Run: ``python -m toolpath.bench --only gcode`` (part of ``make bench``) -> ``reports/bench/gcode.json``.

A G01-dense program as CAM posts write it (``G1 X.. Y..`` lines, a feed word now and then, light
noise so some windows are rough) is written once; every reader then runs on it in its own fresh
process, one after another in one benchmark run, and reports lines per second (the median of
:data:`REPEATS` runs in that process) and its peak resident memory.  What each one does differs,
and the JSON says so: ``gcodeparser`` splits lines into words (no modal state, no positions),
``pygcode`` parses and runs its machine model (positions),
:func:`toolpath.gcode.read_text` interprets to positions with the modal state of every line (what
``toolpath smooth`` needs).  ``pygcode`` is slow enough that it reads a 20,000-line slice;
``toolpath smooth`` runs on the programs of :data:`SMOOTH_CASES`.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

# each runner defines work() -> lines read, timed REPEATS times in one fresh process (median reported), and prints
# {"seconds": s, "runs": [...], "lines": n, "peak_rss_mb": m}; run as `python -c`
REPEATS = 3
_PRELUDE = "import json, sys, time\npath, limit = sys.argv[1], int(sys.argv[2])\n"
# VmHWM, not ru_maxrss: Linux carries ru_maxrss over exec from the forked parent (the benchmark holds torch)
_FOOTER = (f"runs = []\nfor _ in range(globals().get('REPEATS', {REPEATS})):\n"
           "    t0 = time.perf_counter()\n    n = work()\n    runs.append(time.perf_counter() - t0)\n"
           "seconds = sorted(runs)[len(runs) // 2]\n"
           "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]\n"
           "print(json.dumps({'seconds': seconds, 'runs': runs, 'lines': n, 'peak_rss_mb': int(hwm) / 1024}))\n")
RUNNERS = {
    "toolpath.gcode": ("interprets to positions and per-line modal state",
                       "from toolpath.gcode import read_text\ntext = open(path).read()\n"
                       "def work():\n    return len(read_text(text).lines)\n"),
    "gcodeparser": ("splits lines into words: no modal state, no positions",
                    "from gcodeparser import GcodeParser\ntext = open(path).read()\n"
                    "def work():\n    GcodeParser(text)\n    return len(text.splitlines())\n"),
    "pygcode": ("parses each line and runs its machine model (positions)",
                "from pygcode import Line, Machine\nlines = open(path).read().splitlines()[:limit]\n"
                "def work():\n    m = Machine()\n    for text in lines:\n        m.process_block(Line(text).block)\n"
                "    return len(lines)\n"),
}
PYGCODE_LINES = 20_000


def _moves(first: int, count: int, rng: np.random.Generator, spikes: float) -> str:
    s = (first + np.arange(count)) * 0.2
    x = 100.0 * np.cos(s / 400.0) + rng.normal(0.0, 0.002, count)
    y = 100.0 * np.sin(s / 400.0) + np.where(rng.random(count) < spikes, rng.normal(0.0, 0.05, count), 0.0)
    return "".join(f"G1 X{a:.3f} Y{b:.3f}" + (" F1200\n" if (first + k) % 500 == 0 else "\n")
                   for k, (a, b) in enumerate(zip(x, y, strict=True)))


_HEAD, _TAIL = "G21 G90 G17\nG0 X100 Y0\nG1 Z-1 F300\n", "G0 Z5\nM30\n"


def dense_program(lines: int, seed: int = 0, spikes: float = 0.02) -> str:
    """``lines`` G1 moves along a wavy contour (0.2 mm steps, noise of a few microns, and a share
    ``spikes`` of the points off by ~50 um: with 2 %, about a quarter of the windows are rough)."""
    return _HEAD + _moves(0, lines, np.random.default_rng(seed), spikes) + _TAIL


def write_dense(path: Path, lines: int, seed: int = 0, spikes: float = 0.02, block: int = 1_000_000) -> None:
    """:func:`dense_program`'s kind of program at any length, written a block of lines at a time so a
    10-million-line program never sits in memory."""
    rng = np.random.default_rng(seed)
    with path.open("w") as out:
        out.write(_HEAD)
        for first in range(0, lines, block):
            out.write(_moves(first, min(block, lines - first), rng, spikes))
        out.write(_TAIL)


def _run(code: str, path: Path, limit: int) -> dict:
    done = subprocess.run([sys.executable, "-c", _PRELUDE + code + _FOOTER, str(path), str(limit)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        return {"error": (done.stderr.strip().splitlines() or ["failed"])[-1][:300]}
    out = json.loads(done.stdout.strip().splitlines()[-1])
    out["lines_per_s"] = out["lines"] / out["seconds"] if out["seconds"] > 0 else None
    return out


def _smooth(path: Path, method: str, report: bool, repeats: int) -> dict:
    """``toolpath smooth`` end to end (start-up excluded: timed inside the process)."""
    flags = f"'--method', {method!r}" + (", '--report', path + '.json'" if report else "")
    code = ("from toolpath.smooth.command import main\nout = path + '.out'\n"
            "def work():\n"
            f"    assert main([path, '-o', out, '--force', {flags}]) == 0\n"
            "    return sum(1 for _ in open(path))\n")
    return _run(code.replace("def work", f"REPEATS = {repeats}\ndef work"), path, 0)


#: name: (lines, share of spiked points, --method, --report, repeats).  "clean": every window smooth
#: already (read, classify, verify, write); "rough": 2 % spikes, a quarter of the windows smoothed;
#: "dispatch": by category, NACOA on category 4 (tens of ms a window); "report": the machining time planned too;
#: "10M": the memory of a 10-million-line program, one run.
SMOOTH_CASES = {
    "mean, clean": (1_000_000, 0.0, "mean", False, REPEATS),
    "mean, rough": (200_000, 0.02, "mean", False, REPEATS),
    "dispatch, rough": (200_000, 0.02, "dispatch", False, REPEATS),
    "mean, clean, --report": (200_000, 0.0, "mean", True, REPEATS),
    "mean, clean, 10M lines": (10_000_000, 0.0, "mean", False, 1),
}


def measure(lines: int = 1_000_000, seed: int = 0, cases: dict | None = None) -> dict:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "dense.nc"
        path.write_text(dense_program(lines, seed))
        readers = {name: {"does": does, **_run(code, path, PYGCODE_LINES if name == "pygcode" else lines + 10)}
                   for name, (does, code) in RUNNERS.items()}
        path.unlink()
        smooth = {}
        for name, (count, spikes, method, report, repeats) in (SMOOTH_CASES if cases is None else cases).items():
            program = Path(folder) / "smooth.nc"
            write_dense(program, count, seed, spikes)
            smooth[name] = {"lines_in_file": count + 5, "spikes": spikes, "method": method, "report": report,
                            **_smooth(program, method, report, repeats)}
            program.unlink()
    ours = readers["toolpath.gcode"].get("lines_per_s") or 0.0
    return {"file": {"lines": lines + 6, "kind": "G01-dense, 0.2 mm steps, light noise", "seed": seed},
            "targets": {"read_lines_per_s": 1_000_000, "smooth_lines_per_s": 100_000, "peak_rss_mb_10M_lines": 500},
            "readers": readers, "smooth": smooth,
            "ratio_ours_to": {name: ours / r["lines_per_s"] for name, r in readers.items()
                              if name != "toolpath.gcode" and r.get("lines_per_s")}}
