"""Cross-shape matrix and real G-code evaluation.  Run: python -m toolpath.stages.generalise

Reads every shape's windows and the trained MCRL and baselines; picks the best baseline by mean
validation accuracy; trains the MCRL on all three shapes; labels the real programs of
``paths.corpus`` with the exact rule (files with unsupported features are listed with the reader's
message; a missing folder is reported, not an error) and scores the all-shapes MCRL on them.
Writes ``<metrics>/generalise.json`` and ``models/all/<model>.pt``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch
from omegaconf import OmegaConf

from toolpath import config, tracking
from toolpath.gcode import GCodeError, ReaderOptions, read_file
from toolpath.labels import label_program
from toolpath.models.registry import split_schedule
from toolpath.stages._common import load_checkpoint, load_windows, save_checkpoint, write_json
from toolpath.training.classifier import TorchClassifier, from_checkpoint, to_checkpoint
from toolpath.training.generalise import best_by_validation, cross_shape_matrix
from toolpath.training.metrics import classification_metrics

GCODE_SUFFIXES = {".nc", ".ngc", ".gcode", ".tap", ".cnc", ".txt"}


def corpus_windows(folder: Path, options: ReaderOptions, size: int, stride: int) -> tuple[dict, list[np.ndarray]]:
    """Per-file summary and the windows of every readable real program in ``folder``."""
    if not folder.is_dir():
        return {"skipped": f"corpus folder {folder} not found"}, []
    files, windows = {}, []
    for path in sorted(p for p in folder.iterdir() if p.suffix.lower() in GCODE_SUFFIXES):
        try:
            w = label_program(read_file(path, options), size, stride)
        except GCodeError as exc:
            files[path.name] = {"skipped": exc.message, "line": exc.line}
            continue
        files[path.name] = {"windows": len(w), "class_count": np.bincount(w.label, minlength=5)[1:].tolist()}
        windows.append((w.windows, w.label))
    return {"files": files}, windows


def _val_accuracy(path: Path) -> float:
    """Validation accuracy from a train metrics file, or exit naming the file and the problem."""
    try:
        return float(json.loads(path.read_text())["val"]["accuracy"])
    except FileNotFoundError:
        raise SystemExit(f"{path}: train metrics not found; run `dvc repro train` first") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"{path}: malformed train metrics ({exc!r})") from None


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    gen, common = cfg.generalise, cfg.train.common
    torch.set_num_threads(common.threads)
    torch.use_deterministic_algorithms(True)
    data = {s: load_windows(Path(cfg.paths.windows) / f"{s}.npz") for s in cfg.shapes}
    subset = {s: {k: (d["windows"][d["split"] == k], d["label"][d["split"] == k]) for k in range(3)}
              for s, d in data.items()}
    val_acc = {b: float(np.mean([_val_accuracy(Path(cfg.paths.metrics) / "train" / s / f"{b}.json")
                                 for s in cfg.shapes])) for b in gen.baselines}
    best = best_by_validation(val_acc)
    with tracking.stage_run("generalise", config.flat(gen, "generalise")):
        import mlflow

        result = {"best_baseline": best, "baseline_val_accuracy": val_acc, "cross_shape": {}}
        for name in (gen.model, best):
            clfs = {s: from_checkpoint(load_checkpoint(Path(cfg.paths.models) / s / f"{name}.pt")) for s in cfg.shapes}
            result["cross_shape"][name] = cross_shape_matrix(clfs, {s: subset[s][2] for s in cfg.shapes})
        stack = {k: tuple(np.concatenate([subset[s][k][i] for s in cfg.shapes]) for i in (0, 1)) for k in (0, 1)}
        settings = {**OmegaConf.to_container(gen.schedule), "patience": common.patience,
                    "seed": config.seed_for(cfg.seed, "generalise", gen.model)}
        network, _ = split_schedule(OmegaConf.to_container(cfg.models[gen.model], resolve=True))
        clf = TorchClassifier(network, settings, common.class_weight)
        clf.fit(*stack[0], *stack[1])
        save_checkpoint(to_checkpoint(clf), Path(cfg.paths.models) / "all" / f"{gen.model}.pt")
        result["all_shapes"] = {s: classification_metrics(subset[s][2][1], clf.predict_proba(subset[s][2][0]))
                                for s in cfg.shapes}
        summary, real = corpus_windows(Path(cfg.paths.corpus), ReaderOptions(**cfg.gcode.read),
                                       cfg.label.window, cfg.label.stride)
        if real:
            X, y = np.concatenate([w for w, _ in real]), np.concatenate([lab for _, lab in real])
            summary["metrics"] = classification_metrics(y, clf.predict_proba(X))
            summary["majority_accuracy"] = float(np.bincount(y).max() / len(y))
        result["real_gcode"] = summary
        write_json(result, Path(cfg.paths.metrics) / "generalise.json")
        mlflow.log_metrics({k: v for k, v in config.flat(result).items()
                            if isinstance(v, int | float) and not isinstance(v, bool)})


if __name__ == "__main__":
    main()
