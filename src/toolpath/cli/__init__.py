"""The ``toolpath`` command (``pyproject.toml``'s entry point): the tools around the pipeline, one
sub-command each.  The stages themselves run through ``dvc repro`` (:mod:`toolpath.stages`).

    toolpath smooth IN.nc -o OUT.nc [--tolerance 0.01] [--report R.json|R.html]   smooth a program (Sec. 5.3)
    toolpath stage-times [--out FILE] -- dvc repro     time every DVC stage of a command
"""

from __future__ import annotations

import argparse
import sys

COMMANDS = {"smooth": ("toolpath.smooth.command", "smooth a rough G-code program within a two-sided tolerance"),
            "stage-times": ("toolpath.pipeline.stage_times", "time every DVC stage of a command (e.g. dvc repro)")}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(prog="toolpath", description="Tools around the toolpath-lab pipeline.")
    parser.add_argument("command", choices=sorted(COMMANDS), help="; ".join(f"{k}: {v[1]}" for k, v in
                                                                            COMMANDS.items()))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the sub-command's own arguments (see --help)")
    args = parser.parse_args(argv[:1])
    from importlib import import_module

    module = import_module(COMMANDS[args.command][0])
    sys.argv[0] = f"toolpath {args.command}"
    return int(module.main(argv[1:]) or 0)
