"""Cross-shape matrix and real G-code evaluation.  Run: python -m toolpath.stages.generalise

Reads every shape's windows and the trained MCRL and baselines; picks the best baseline by mean
validation accuracy; trains the MCRL on all three shapes; labels the real programs of
``paths.corpus`` with the exact rule (files with unsupported features are listed with the reader's
message; a missing folder is reported, not an error) and scores the all-shapes MCRL on them.
Writes ``<metrics>/generalise.json`` and the all-shapes model
(:meth:`~toolpath.pipeline.artifacts.Layout.generalised`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from toolpath.gcode import GCodeError, ReaderOptions, read_file
from toolpath.geometry.labels import label_program
from toolpath.geometry.labels.windows import arc_share
from toolpath.models.training.classifier import TorchClassifier, to_checkpoint
from toolpath.models.training.generalise import best_by_validation, corpus_report, cross_shape_matrix
from toolpath.models.training.metrics import classification_metrics
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.artifacts import Split

GCODE_SUFFIXES = {".nc", ".ngc", ".gcode", ".tap", ".cnc", ".txt"}


def corpus_windows(folder: Path, options: ReaderOptions, size: int, stride: int,
                   bounds: tuple[float, float, float]) -> tuple[dict, list[np.ndarray]]:
    """Per-file summary and the windows of every readable real program in ``folder``."""
    if not folder.is_dir():
        return {"skipped": f"corpus folder {folder} not found"}, []
    files, windows = {}, []
    for path in sorted(p for p in folder.iterdir() if p.suffix.lower() in GCODE_SUFFIXES):
        try:
            program = read_file(path, options)
            w = label_program(program, size, stride, bounds)
        except GCodeError as exc:
            files[path.name] = {"skipped": exc.message, "line": exc.line}
            continue
        arcs = arc_share(program, size, stride)
        files[path.name] = {"windows": len(w), "class_count": np.bincount(w.label, minlength=5)[1:].tolist(),
                            "arc_windows": int((arcs > 0.5).sum())}
        windows.append((w.windows, w.label, arcs))
    return {"files": files}, windows


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    across, common, layout = cfg.generalise, cfg.train.common, settings.layout(cfg)
    torch.set_num_threads(across.threads)
    torch.use_deterministic_algorithms(True)
    data = {s: artifacts.load_windows(layout.windows_file(s), s) for s in cfg.shapes}
    tests = {s: d.part(Split.TEST) for s, d in data.items()}
    val_acc = {b: float(np.mean([_val_accuracy(layout.train_metrics(s, b), s, b) for s in cfg.shapes]))
               for b in across.baselines}
    best = best_by_validation(val_acc)
    with tracking.stage_run("generalise", config.flat(across, "generalise")):
        import mlflow

        result = {"best_baseline": best, "baseline_val_accuracy": val_acc, "cross_shape": {}}
        for name in (across.model, best):
            clfs = {s: artifacts.load_classifier(layout.checkpoint(s, name), f"train@{name}") for s in cfg.shapes}
            result["cross_shape"][name] = cross_shape_matrix(clfs, tests)
        stack = {split.label: tuple(np.concatenate([d.part(split)[i] for d in data.values()]) for i in (0, 1))
                 for split in (Split.TRAIN, Split.VAL)}
        network, train_settings = settings.all_shapes_training(cfg)
        clf = TorchClassifier(network, train_settings, common.class_weight).fit(*stack["train"], *stack["val"])
        artifacts.save_checkpoint(to_checkpoint(clf), layout.generalised(across.model))
        result["all_shapes"] = {s: classification_metrics(y, clf.predict_proba(X)) for s, (X, y) in tests.items()}
        summary, real = corpus_windows(layout.corpus, settings.reader_options(cfg), cfg.label.window,
                                       cfg.label.stride, settings.bounds(cfg))
        if real:
            X, y, arcs = (np.concatenate([part[k] for part in real]) for k in range(3))
            proba = clf.predict_proba(X)
            summary["metrics"] = classification_metrics(y, proba)
            summary["majority_accuracy"] = float(np.bincount(y).max() / len(y))
            summary["by_origin"] = corpus_report(y, proba, arcs)
        result["real_gcode"] = summary
        artifacts.write_json(result, layout.generalise_metrics)
        mlflow.log_metrics({k: v for k, v in config.flat(result).items()
                            if isinstance(v, int | float) and not isinstance(v, bool)})


def _val_accuracy(path: Path, shape: str, model: str) -> float:
    """Validation accuracy (mean over the training seeds) from a train metrics file, or exit naming the
    file and the stage to rerun."""
    metrics = artifacts.read_json(path, f"train@{model}")
    try:
        return float(metrics["replicates"]["val"]["accuracy"]["mean"] or 0.0)  # None: every seed degenerate
    except (KeyError, TypeError, ValueError) as exc:
        raise artifacts.ArtifactError(path, f"malformed train metrics ({exc!r})", f"train@{model}") from None


if __name__ == "__main__":
    main()
