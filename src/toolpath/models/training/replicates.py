"""One training configuration under several seeds: the spread behind every Table 3 figure.

A result that moves with the initialisation is not a result: each model is trained ``replicates``
times with seeds derived from its name, the figures are reported as mean and standard deviation
over those runs, and the accuracy interval is a bootstrap over test *programs* of the per-window
correctness averaged over the seeds.  Replicate 0 is the checkpoint the later stages use (QAT,
inference); its own metrics stay under ``test`` / ``val``.

The runs are independent, so :func:`run_all` spreads them over worker processes (one torch thread
each: results depend on the thread count, so it is fixed, never "whatever is free").
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import as_completed
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolpath.models.training.metrics import DEGENERATE, degenerate, program_bootstrap
from toolpath.pipeline.warm_pool import process_pool

SCALARS = ("accuracy", "loss", "precision", "recall", "f1", "auc")


@dataclass(frozen=True)
class Job:
    """One training run: a model config, its settings (with the replicate's seed) and its replicate number."""

    model: str
    replicate: int
    network: Mapping[str, Any]
    settings: Mapping[str, Any]
    class_weight: str | None = None
    shape: str = ""  # the key of the windows it trains on (run_all's ``parts`` and ``programs``)


@dataclass
class Outcome:
    """What one run gives back: its checkpoint, metrics, per-epoch history, seconds and, per test
    window, whether the prediction was right (for the program bootstrap of the seed mean)."""

    job: Job
    checkpoint: dict
    metrics: dict
    history: list
    seconds: float
    test_correct: np.ndarray
    started: float = 0.0  # wall clock (epoch seconds) when the run began: its MLflow run spans it
    test_predicted: np.ndarray | None = None  # the category predicted for each test window (paired comparisons)


_DATA: dict[str, Any] = {}


def deterministic_torch(threads: int) -> None:
    """``threads`` intra-op threads and deterministic kernels, for a process that trains in eager mode.
    ``torch.use_deterministic_algorithms`` also imports inductor (a slow import in every process) to set its
    flag for ``torch.compile``, which no training process uses: the eager flag is set directly when
    this torch has the hook, and checked."""
    import torch

    torch.set_num_threads(threads)
    set_flag = getattr(torch._C, "_set_deterministic_algorithms", None)
    if set_flag is None:
        torch.use_deterministic_algorithms(True)
    else:
        set_flag(True, warn_only=False)
    if not torch.are_deterministic_algorithms_enabled() or torch.is_deterministic_algorithms_warn_only_enabled():
        raise RuntimeError("torch did not switch to deterministic algorithms")


def _init(parts: Mapping[str, Mapping[str, tuple[np.ndarray, np.ndarray]]],
          programs: Mapping[str, Mapping[str, np.ndarray]], threads: int) -> None:
    deterministic_torch(threads)
    _DATA.update(parts=parts, programs=programs)


def _run(job: Job) -> Outcome:
    from toolpath.models.training.classifier import fit_and_score, to_checkpoint

    parts, started = _DATA["parts"][job.shape], time.time()
    clf, metrics, history, seconds = fit_and_score(job.network, job.settings, job.class_weight, parts,
                                                   programs=_DATA["programs"][job.shape])
    predicted = clf.predict(parts["test"][0]) if "test" in parts else np.zeros(0, np.int64)
    correct = predicted == parts["test"][1] if "test" in parts else np.zeros(0, bool)
    return Outcome(job, to_checkpoint(clf), metrics, history, seconds, correct, started, predicted)


def run_all(jobs: Sequence[Job], parts: Mapping[str, Mapping[str, tuple[np.ndarray, np.ndarray]]],
            programs: Mapping[str, Mapping[str, np.ndarray]], workers: int = 1, threads: int = 1) -> Iterator[Outcome]:
    """Run every job, ``workers`` at a time (in this process when 1), yielding outcomes as they
    finish.  ``parts`` and ``programs``: per :attr:`Job.shape`, the splits (windows, labels) and each
    window's program.  Each run's result depends only on its job and ``threads``, never on the schedule."""
    if workers <= 1:
        _init(parts, programs, threads)
        yield from map(_run, jobs)
        return
    # not forked from this process: a forked torch with live OpenMP threads can hang
    with process_pool(workers, initializer=_init, initargs=(parts, programs, threads)) as pool:
        futures = [pool.submit(_run, job) for job in jobs]
        yield from (future.result() for future in as_completed(futures))


def summarise(outcomes: Sequence[Outcome], test_programs: np.ndarray, seed: int) -> dict:
    """Mean, standard deviation (ddof 1) and per-seed values (``seed<replicate>``) of every Table 3
    scalar over the replicates, how many replicates predicted one class only, and the program
    bootstrap of the seed-mean accuracy.  A degenerate replicate is counted, and its figures are left out of the
    mean: the figures describe the models that learned something."""
    ordered = sorted(outcomes, key=lambda o: o.job.replicate)
    learned = [o for o in ordered if not degenerate(o.metrics["test"])]
    summary: dict[str, Any] = {"seeds": [int(o.job.settings.get("seed", 0)) for o in ordered],
                               "degenerate": len(ordered) - len(learned), "replicates": len(ordered),
                               "degenerate_replicates": [o.job.replicate for o in ordered if o not in learned]}
    for split in ("val", "test"):
        figures = {}
        for key in SCALARS:
            # keyed, not a list: `dvc metrics show` lists numbers under keys only
            values = {f"seed{o.job.replicate}": o.metrics[split][key] for o in ordered}
            kept = np.array([o.metrics[split][key] for o in learned if o.metrics[split][key] is not None], float)
            figures[key] = {"mean": float(kept.mean()) if len(kept) else None,
                            "sd": float(kept.std(ddof=1)) if len(kept) > 1 else None, "per_seed": values}
        summary[split] = figures
    if learned:
        correct = np.mean([o.test_correct for o in learned], axis=0)
        summary["accuracy_ci"] = program_bootstrap(correct, test_programs, seed)
    return summary


def best_learned(summaries: Mapping[str, Mapping[str, Any]]) -> str | None:
    """The one definition of a shape's best learned model (README, report, MLflow tags and registry):
    the highest mean *validation* macro F1 over seeds among learned models with a non-degenerate seed,
    chosen on validation so the test figures reported for it stay held out; ties go to the first name."""
    scored = {m: s["val"]["f1"]["mean"] for m, s in sorted(summaries.items())
              if m != "rule" and s["degenerate"] < s["replicates"] and s["val"]["f1"]["mean"] is not None}
    return max(scored, key=scored.get) if scored else None


def describe(summary: Mapping[str, Any]) -> str | None:
    """How a table shows a model none or only some of whose replicates learned (None: all did)."""
    if summary["degenerate"] == 0:
        return None
    if summary["degenerate"] == summary["replicates"]:
        return DEGENERATE
    return f"{DEGENERATE} in {summary['degenerate']} of {summary['replicates']} seeds"


def job_order(jobs: Sequence[Job], cost: Callable[[Job], float]) -> list[Job]:
    """Longest first, so two workers finish together instead of one waiting on the last big run."""
    return sorted(jobs, key=lambda j: (-cost(j), j.model, j.replicate))


def saved_predictions(outcomes: Sequence[Outcome]) -> dict[str, np.ndarray]:
    """One model's runs as its test-predictions file holds them: ``predicted`` (replicates x test windows,
    in replicate order) and ``degenerate`` (per replicate: it predicted one class)."""
    ordered = sorted(outcomes, key=lambda o: o.job.replicate)
    return {"predicted": np.stack([o.test_predicted for o in ordered]).astype(np.int64),
            "degenerate": np.array([degenerate(o.metrics["test"]) for o in ordered])}


def learned_predictions(saved: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """The predictions of the replicates that learned (of a :func:`saved_predictions` record); None if none did."""
    kept = saved["predicted"][~saved["degenerate"].astype(bool)]
    return kept if len(kept) else None


def paired(learned: Mapping[str, np.ndarray | None], anchors: Sequence[str], inputs: Mapping[str, str],
           y: np.ndarray, programs: np.ndarray, seed: Callable[[str, str], int]) -> dict:
    """Each anchor (MCRL on each input) against every other learned model on the same input and the other
    anchors: :func:`~toolpath.models.training.metrics.paired_bootstrap` over the test programs and the seeds
    that learned (``learned``: per model, :func:`learned_predictions`; a model none of whose seeds learned is
    named, not compared)."""
    from toolpath.models.training.metrics import paired_bootstrap

    learned = {m: p for m, p in learned.items() if m in inputs and p is not None}
    out: dict[str, dict] = {}
    for anchor in (a for a in anchors if a in learned):
        rivals = [m for m in inputs if m != anchor and (inputs[m] == inputs[anchor] or m in anchors)]
        out[anchor] = {m: paired_bootstrap(learned[anchor], learned[m], y, programs, seed(anchor, m))
                       if m in learned else {"verdict": DEGENERATE} for m in rivals}
    return out


def logistic_reference(parts: Mapping[str, tuple[np.ndarray, np.ndarray]], inputs: Sequence[str],
                       test_programs: np.ndarray, seed: int) -> dict:
    """Per input, the logistic-regression reference (:func:`toolpath.models.linear.fit_logistic`) trained
    on the training windows, in :func:`summarise`'s layout (one deterministic run, no sd), so Table 3 shows
    it as a row; its test accuracy gets the program bootstrap interval."""
    from toolpath.models.linear import features, fit_logistic, probabilities
    from toolpath.models.training.metrics import CLASSES, classification_metrics

    out = {}
    for name in inputs:
        model = fit_logistic(*parts["train"], name)
        scored = {split: classification_metrics(parts[split][1], probabilities(model, parts[split][0], name, CLASSES))
                  for split in ("val", "test")}
        summary: dict[str, Any] = {"seeds": [], "replicates": 1, "degenerate_replicates": [],
                                   "degenerate": int(degenerate(scored["test"]))}
        for split, metrics in scored.items():
            summary[split] = {k: {"mean": metrics[k], "sd": None, "per_seed": {"seed0": metrics[k]}} for k in SCALARS}
        correct = model.predict(features(parts["test"][0], name)) == parts["test"][1]
        summary["accuracy_ci"] = program_bootstrap(correct, test_programs, seed)
        out[name] = summary
    return out


def comparisons(learned: Mapping[str, np.ndarray | None], networks: Mapping[str, Mapping[str, Any]],
                parts: Mapping[str, tuple[np.ndarray, np.ndarray]], test_programs: np.ndarray,
                seed: Callable[..., int]) -> dict[str, dict]:
    """The compare stage's figures of one shape: ``paired`` (:func:`paired`: MCRL on each input against
    the networks on its input) and ``logistic`` (:func:`logistic_reference` on every input a network
    reads).  ``learned``: per learned model, :func:`learned_predictions`; ``networks``: their configs;
    ``seed(kind, *names)``: the seed of one bootstrap ("paired", anchor, rival; "bootstrap", "logistic")."""
    inputs = {m: config.get("inputs", "turning") for m, config in networks.items()}
    anchors = [m for m, config in networks.items() if config["_target_"] == "toolpath.models.MCRL"]
    return {"paired": paired(learned, anchors, inputs, parts["test"][1], test_programs,
                             lambda a, b: seed("paired", a, b)),
            "logistic": logistic_reference(parts, sorted(set(inputs.values())), test_programs,
                                           seed("bootstrap", "logistic"))}
