"""The one protocol's learning rates (Table 3's note): the same grid for every model, on validation only.

Every model of ``train.protocol.models`` is trained at each rate of ``train.protocol.tune.lr`` on the
training programs of ``train.protocol.tune.shape`` with replicate 0's seed and the protocol's
settings, and scored on that shape's validation programs; the test split is never loaded.  A model's
rate is the one with the highest validation macro F1 (the score that names a shape's best model;
ties go to the lower rate).  Writes ``reports/tuning/protocol.json`` (every trial, the chosen rates),
``protocol.md`` (the table) and ``protocol.png`` (the tuning curve: best validation F1 against
trials).  ``train.protocol.lr`` in ``conf/train/default.yaml`` must hold the chosen rates (a test
compares them).

Run from the repository root, after `dvc repro label@<shape>`:

    python -m toolpath.sweep.protocol                 # the default profile's grid
    python -m toolpath.sweep.protocol +experiment=smoke
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

OUT = Path("reports/tuning")


def jobs(cfg) -> list:
    """One training job per model and rate, each with the protocol's settings and replicate 0's seed."""
    from toolpath.pipeline.settings import training
    from toolpath.training.replicates import Job

    protocol, shape = cfg.train.protocol, cfg.train.protocol.tune.shape
    out = []
    for model in protocol.models:
        network, settings = training(cfg, shape, model)
        out += [Job(model, 0, network, {**settings, "lr": float(lr)}, cfg.train.common.class_weight)
                for lr in protocol.tune.lr]
    return out


def validation_parts(cfg) -> tuple[dict, dict]:
    """(windows and labels, programs) of the tuning shape's train and val splits: no test windows."""
    from toolpath.pipeline.artifacts import Split, load_windows
    from toolpath.pipeline.settings import layout

    shape = cfg.train.protocol.tune.shape
    windows = load_windows(layout(cfg).windows_file(shape), shape)
    kept = (Split.TRAIN, Split.VAL)
    return {s.label: windows.part(s) for s in kept}, {s.label: windows.program[windows.split == s] for s in kept}


def choose(trials: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """Each model's rate: the highest validation macro F1, ties to the lower rate."""
    chosen: dict[str, tuple[float, float]] = {}
    for t in sorted(trials, key=lambda t: (t["model"], t["lr"])):
        if t["model"] not in chosen or t["val_f1"] > chosen[t["model"]][1]:
            chosen[t["model"]] = (t["lr"], t["val_f1"])
    return {m: lr for m, (lr, _) in chosen.items()}


def table(trials: Sequence[Mapping[str, Any]], chosen: Mapping[str, float], shape: str) -> str:
    rates = sorted({t["lr"] for t in trials})
    lines = [f"Validation accuracy / macro F1 (%) on {shape}'s validation programs, one seed; "
             "**bold**: the rate chosen (highest F1).", "",
             "| model | " + " | ".join(f"lr {r:g}" for r in rates) + " |",
             "|---|" + "---|" * len(rates)]
    by_key = {(t["model"], t["lr"]): t for t in trials}
    for model in dict.fromkeys(t["model"] for t in trials):
        cells = []
        for r in rates:
            t = by_key[(model, r)]
            cell = f"{100 * t['val_accuracy']:.2f} / {100 * t['val_f1']:.2f}"
            cells.append(f"**{cell}**" if chosen[model] == r else cell)
        lines.append(f"| {model} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def curve(trials: Sequence[Mapping[str, Any]], path: Path) -> None:
    """Best validation F1 so far against trials (in the grid's order), one line per model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for model in dict.fromkeys(t["model"] for t in trials):
        scores = [t["val_f1"] for t in sorted((t for t in trials if t["model"] == model), key=lambda t: t["lr"])]
        best = [max(scores[: i + 1]) for i in range(len(scores))]
        ax.plot(range(1, len(best) + 1), [100 * b for b in best], marker="o", label=model)
    ax.set(xlabel="trials (learning-rate grid, ascending)", ylabel="best validation macro F1 (%)")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120, metadata={"Software": None})
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    from toolpath.pipeline.config import compose_config
    from toolpath.pipeline.workers import progress
    from toolpath.training.replicates import run_all

    cfg = compose_config(Path.cwd(), sys.argv[1:] if argv is None else argv)
    parts, programs = validation_parts(cfg)
    todo = jobs(cfg)
    trials = []
    for outcome in progress(run_all(todo, parts, programs, cfg.train.common.workers, cfg.train.common.threads),
                            "protocol", total=len(todo)):
        val = outcome.metrics["val"]
        trials.append({"model": outcome.job.model, "lr": outcome.job.settings["lr"], "val_accuracy": val["accuracy"],
                       "val_f1": val["f1"], "val_loss": val["loss"], "seconds": round(outcome.seconds, 1),
                       "seed": outcome.job.settings["seed"]})
    trials.sort(key=lambda t: (list(cfg.train.protocol.models).index(t["model"]), t["lr"]))
    chosen, shape = choose(trials), str(cfg.train.protocol.tune.shape)
    OUT.mkdir(parents=True, exist_ok=True)
    summary = {"shape": shape, "split": "val", "score": "macro F1", "settings": dict(cfg.train.protocol.settings),
               "grid": [float(r) for r in cfg.train.protocol.tune.lr], "chosen": chosen, "trials": trials}
    (OUT / "protocol.json").write_text(json.dumps(summary, indent=1) + "\n")
    (OUT / "protocol.md").write_text(table(trials, chosen, shape))
    curve(trials, OUT / "protocol.png")
    print(f"wrote {OUT}/protocol.json, protocol.md, protocol.png; chosen: {chosen}")


if __name__ == "__main__":
    main()
