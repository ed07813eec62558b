"""The one protocol's learning rates (Table 3's note): the same grid for every model, on validation only.

Every model of ``train.protocol.models`` is trained at each rate of ``train.protocol.tune.lr`` on the
training programs of ``train.protocol.tune.shape`` with replicate 0's seed and the protocol's
settings, and scored on that shape's validation programs; the test split is never loaded.  A model's
rate is the one with the highest validation macro F1 (the score that names a shape's best model;
ties go to the lower rate).  Writes ``reports/tuning/protocol.json`` (every trial, the chosen rates),
``protocol.md`` (the table) and ``protocol.png`` (the tuning curve: best validation F1 against
trials).  ``train.protocol.lr`` in ``conf/train/default.yaml`` must hold the chosen rates (a test
compares them).

Run from the repository root, after `dvc repro generate@<shape>`:

    python -m toolpath.sweep.protocol                 # the default profile's grid
    python -m toolpath.sweep.protocol +experiment=smoke
"""

from __future__ import annotations

import itertools
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

OUT = Path("reports/tuning")


def structures(cfg, model: str) -> list[dict[str, Any]]:
    """Every combination of the model's own structural options in ``train.protocol.tune.structure.<model>``
    (e.g. MCRL's auxiliary heads: ``aux_loss_weight: [0.0, 0.5]``); ``[{}]`` for a model without any."""
    from omegaconf import OmegaConf

    node = (cfg.train.protocol.tune.get("structure") or {}).get(model) or {}
    options = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else dict(node)
    return [dict(zip(options, values, strict=True)) for values in itertools.product(*options.values())]


def jobs(cfg) -> list:
    """One training job per model, rate and structural option, each with the protocol's settings and
    replicate 0's seed."""
    from toolpath.models.training.replicates import Job
    from toolpath.pipeline.settings import training

    protocol, shape = cfg.train.protocol, cfg.train.protocol.tune.shape
    out = []
    for model in protocol.models:
        network, settings = training(cfg, shape, model)
        out += [Job(model, 0, network, {**settings, **option, "lr": float(lr)}, cfg.train.common.class_weight)
                for option in structures(cfg, model) for lr in protocol.tune.lr]
    return out


def validation_parts(cfg) -> tuple[dict, dict]:
    """(windows and labels, programs) of the tuning shape's train and val splits: no test windows."""
    from toolpath.pipeline.artifacts import Split, load_windows
    from toolpath.pipeline.settings import layout

    shape = cfg.train.protocol.tune.shape
    windows = load_windows(layout(cfg).windows_file(shape), shape)
    kept = (Split.TRAIN, Split.VAL)
    return {s.label: windows.part(s) for s in kept}, {s.label: windows.program[windows.split == s] for s in kept}


def choose(trials: Sequence[Mapping[str, Any]]) -> tuple[dict[str, float], dict[str, dict[str, Any]]]:
    """Each model's (rate, structural option): the highest validation macro F1; a tie goes to the earlier
    trial in the listed order (options as configured, rates ascending).  Returns ({model: rate},
    {model: option}), the second without models that have no option."""
    best: dict[str, tuple[float, dict, float]] = {}
    for t in trials:
        if t["model"] not in best or t["val_f1"] > best[t["model"]][2]:
            best[t["model"]] = (t["lr"], t.get("structure") or {}, t["val_f1"])
    return {m: lr for m, (lr, _, _) in best.items()}, {m: option for m, (_, option, _) in best.items() if option}


def _label(trial: Mapping[str, Any]) -> str:
    option = trial.get("structure") or {}
    return trial["model"] + (" (" + ", ".join(f"{k} {v:g}" for k, v in option.items()) + ")" if option else "")


def table(trials: Sequence[Mapping[str, Any]], chosen: Mapping[str, float], structure: Mapping[str, Mapping],
          shape: str) -> str:
    rates = sorted({t["lr"] for t in trials})
    lines = [f"Validation accuracy / macro F1 (%) on {shape}'s validation programs, one seed; **bold**: the rate "
             "(and structural option) chosen (highest F1).", "",
             "| model | " + " | ".join(f"lr {r:g}" for r in rates) + " |",
             "|---|" + "---|" * len(rates)]
    by_key = {(_label(t), t["lr"]): t for t in trials}
    for label in dict.fromkeys(_label(t) for t in trials):
        cells = []
        for r in rates:
            t = by_key[(label, r)]
            cell = f"{100 * t['val_accuracy']:.2f} / {100 * t['val_f1']:.2f}"
            mine = chosen[t["model"]] == r and (t.get("structure") or {}) == dict(structure.get(t["model"], {}))
            cells.append(f"**{cell}**" if mine else cell)
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def curve(trials: Sequence[Mapping[str, Any]], path: Path) -> None:
    """Best validation F1 so far against trials (in the grid's order), one line per model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for model in dict.fromkeys(t["model"] for t in trials):
        scores = [t["val_f1"] for t in trials if t["model"] == model]  # in the order they were listed
        best = [max(scores[: i + 1]) for i in range(len(scores))]
        ax.plot(range(1, len(best) + 1), [100 * b for b in best], marker="o", label=model)
    ax.set(xlabel="trials (each option's learning-rate grid, ascending)", ylabel="best validation macro F1 (%)")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120, metadata={"Software": None})
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    from toolpath.models.training.replicates import run_all
    from toolpath.pipeline.config import compose_config
    from toolpath.pipeline.workers import progress

    cfg = compose_config(Path.cwd(), sys.argv[1:] if argv is None else argv)
    parts, programs = validation_parts(cfg)
    todo = jobs(cfg)
    trials = []
    for outcome in progress(run_all(todo, {"": parts}, {"": programs}, int(cfg.resources.workers.train),
                                    cfg.train.common.threads),
                            "protocol", total=len(todo)):
        val = outcome.metrics["val"]
        option = {k: outcome.job.settings[k] for k in structures(cfg, outcome.job.model)[0]}
        trials.append({"model": outcome.job.model, "lr": outcome.job.settings["lr"], "structure": option,
                       "val_accuracy": val["accuracy"], "val_f1": val["f1"], "val_loss": val["loss"],
                       "seconds": round(outcome.seconds, 1), "seed": outcome.job.settings["seed"]})
    order = {(j.model, json.dumps({k: j.settings[k] for k in structures(cfg, j.model)[0]}), j.settings["lr"]): n
             for n, j in enumerate(todo)}
    trials.sort(key=lambda t: order[(t["model"], json.dumps(t["structure"]), t["lr"])])
    (chosen, structure), shape = choose(trials), str(cfg.train.protocol.tune.shape)
    OUT.mkdir(parents=True, exist_ok=True)
    summary = {"shape": shape, "split": "val", "score": "macro F1", "settings": dict(cfg.train.protocol.settings),
               "grid": [float(r) for r in cfg.train.protocol.tune.lr], "chosen": chosen,
               "chosen_structure": structure, "trials": trials}
    (OUT / "protocol.json").write_text(json.dumps(summary, indent=1) + "\n")
    (OUT / "protocol.md").write_text(table(trials, chosen, structure, shape))
    curve(trials, OUT / "protocol.png")
    print(f"wrote {OUT}/protocol.json, protocol.md, protocol.png; chosen: {chosen} {structure}")


if __name__ == "__main__":
    main()
