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
``toolpath smooth`` runs on programs of :data:`SMOOTH_LINES` lines (NACOA on every rough window of
the default dispatch costs seconds each).
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
_FOOTER = (f"runs = []\nfor _ in range({REPEATS}):\n"
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
SMOOTH_LINES = {"mean": 50_000, "dispatch": 5_000}  # programs `toolpath smooth` runs on, per --method


def dense_program(lines: int, seed: int = 0) -> str:
    """``lines`` G1 moves along a wavy contour (0.2 mm steps, noise of a few microns, now and then 50 um)."""
    rng = np.random.default_rng(seed)
    s = np.arange(lines) * 0.2
    x = 100.0 * np.cos(s / 400.0) + rng.normal(0.0, 0.002, lines)
    y = 100.0 * np.sin(s / 400.0) + np.where(rng.random(lines) < 0.02, rng.normal(0.0, 0.05, lines), 0.0)
    body = [f"G1 X{a:.3f} Y{b:.3f}" + (" F1200" if k % 500 == 0 else "") for k, (a, b) in enumerate(zip(x, y,
                                                                                                   strict=True))]
    return "G21 G90 G17\nG0 X100 Y0\nG1 Z-1 F300\n" + "\n".join(body) + "\nG0 Z5\nM30\n"


def _run(code: str, path: Path, limit: int) -> dict:
    done = subprocess.run([sys.executable, "-c", _PRELUDE + code + _FOOTER, str(path), str(limit)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        return {"error": (done.stderr.strip().splitlines() or ["failed"])[-1][:300]}
    out = json.loads(done.stdout.strip().splitlines()[-1])
    out["lines_per_s"] = out["lines"] / out["seconds"] if out["seconds"] > 0 else None
    return out


def _smooth(path: Path, method: str) -> dict:
    """``toolpath smooth`` end to end (start-up excluded: timed inside the process)."""
    code = ("from toolpath.cli.smooth import main\nout = path + '.out'\n"
            "def work():\n"
            f"    assert main([path, '-o', out, '--force', '--method', {method!r}]) == 0\n"
            "    return sum(1 for _ in open(path))\n")
    return _run(code, path, 0)


def measure(lines: int = 1_000_000, seed: int = 0) -> dict:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "dense.nc"
        path.write_text(dense_program(lines, seed))
        readers = {name: {"does": does, **_run(code, path, PYGCODE_LINES if name == "pygcode" else lines + 10)}
                   for name, (does, code) in RUNNERS.items()}
        smooth = {}
        for method, count in SMOOTH_LINES.items():  # NACOA on every rough window costs seconds each
            small = Path(folder) / f"dense_{count}.nc"
            small.write_text(dense_program(count, seed))
            smooth[method] = {"lines_in_file": count + 6, **_smooth(small, method)}
    ours = readers["toolpath.gcode"].get("lines_per_s") or 0.0
    return {"file": {"lines": lines + 6, "kind": "G01-dense, 0.2 mm steps, light noise", "seed": seed},
            "targets": {"read_lines_per_s": 1_000_000, "smooth_lines_per_s": 100_000, "peak_rss_mb_10M_lines": 500},
            "readers": readers, "smooth": smooth,
            "ratio_ours_to": {name: ours / r["lines_per_s"] for name, r in readers.items()
                              if name != "toolpath.gcode" and r.get("lines_per_s")}}
