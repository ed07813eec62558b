"""Replicates: mean +- sd over training seeds, degenerate seeds counted and left out, the program
bootstrap of the seed mean, the job order, and Table 3 / the README line built from them."""

import numpy as np
import pytest

from toolpath.models.training.metrics import DEGENERATE, classification_metrics
from toolpath.models.training.replicates import Job, Outcome, best_learned, describe, job_order, summarise

Y = np.array([1, 1, 1, 1, 2, 2, 3, 4])
PROGRAMS = np.array([0, 0, 1, 1, 2, 2, 3, 3])


def outcome(replicate: int, predicted: np.ndarray) -> Outcome:
    proba = np.eye(4)[np.asarray(predicted) - 1] * 0.9 + 0.025
    metrics = {split: classification_metrics(Y, proba) for split in ("val", "test")}
    return Outcome(Job("m", replicate, {}, {"seed": 100 + replicate}), {}, metrics, [], 1.0, predicted == Y)


def summary_of(*predictions) -> dict:
    return summarise([outcome(k, np.asarray(p)) for k, p in enumerate(predictions)], PROGRAMS, seed=0)


def test_mean_and_sample_sd_over_seeds_by_hand():
    right = Y.copy()
    one_wrong = Y.copy()
    one_wrong[4] = 1  # 7 of 8
    two_wrong = one_wrong.copy()
    two_wrong[6] = 4  # 6 of 8
    s = summary_of(right, one_wrong, two_wrong)
    acc = s["test"]["accuracy"]
    assert acc["per_seed"] == {"seed0": 1.0, "seed1": 0.875, "seed2": 0.75}
    assert acc["mean"] == pytest.approx(0.875) and acc["sd"] == pytest.approx(0.125)  # ddof 1
    assert s["seeds"] == [100, 101, 102] and s["degenerate"] == 0 and describe(s) is None
    ci = s["accuracy_ci"]  # over the 4 programs, of the per-window mean correctness
    assert ci["programs"] == 4 and ci["low"] <= 0.875 <= ci["high"]


def test_a_degenerate_seed_is_counted_and_left_out_of_the_mean():
    majority = np.ones_like(Y)
    s = summary_of(Y, majority, Y)
    assert s["degenerate"] == 1 and s["degenerate_replicates"] == [1]
    assert s["test"]["accuracy"]["mean"] == 1.0 and s["test"]["accuracy"]["sd"] == 0.0
    assert s["test"]["accuracy"]["per_seed"]["seed1"] == pytest.approx(0.5)  # still on record
    assert describe(s) == f"{DEGENERATE} in 1 of 3 seeds"
    everything = summary_of(majority, majority)
    assert describe(everything) == DEGENERATE and everything["test"]["accuracy"]["mean"] is None
    assert "accuracy_ci" not in everything


def test_one_replicate_has_no_sd():
    s = summary_of(Y)
    assert s["test"]["f1"]["mean"] == 1.0 and s["test"]["f1"]["sd"] is None


def test_jobs_run_longest_first_with_a_stable_tie_break():
    jobs = [Job(m, r, {}, {}) for m in ("small", "big") for r in range(2)]
    ordered = job_order(jobs, lambda j: 10.0 if j.model == "big" else 1.0)
    assert [(j.model, j.replicate) for j in ordered] == [("big", 0), ("big", 1), ("small", 0), ("small", 1)]


def test_table3_shows_mean_sd_beside_the_paper_and_flags_degenerate_models():
    from toolpath.reports.summary import table3_summary
    from toolpath.reports.tables import table3

    wrong = Y.copy()
    wrong[4] = 1
    seeds = summary_of(Y, wrong)  # accuracy 1.0 and 0.875
    majority = summary_of(np.ones_like(Y), np.ones_like(Y))
    rule = summary_of(Y)
    table = table3("gear", {"mcrl": seeds, "lstm": majority, "rule": rule})
    mcrl, lstm, rule_row = table.rows
    assert mcrl[1] == "**93.75 +- 8.84** / 94.75 (-1.00)"  # worse than the paper: negative; the best learned
    assert lstm == ["lstm", *[DEGENERATE] * 6, "-", "2"]
    assert rule_row[1] == "100.00 / -" and rule_row[-1] == "1"  # no sd for one run, no paper row, never bold
    line = table3_summary({"gear": {"mcrl_xy": {"replicates": seeds}, "mcrl": {"replicates": majority},
                                    "lstm": {"replicates": majority},
                                    "rule": {"replicates": rule, "test": {"accuracy": 1.0}}}})
    # the paper's figure beside MCRL on the paper's input (Table 3a), not beside ours on turning terms
    assert f"| gear | 93.8 +- 8.8 % / 94.4 +- 7.9 % (94.8 % / 94.8 %) | {DEGENERATE} | " in line
    assert "| 100.0 % |" in line
    xy = table3("gear", {"mcrl_xy": seeds}, "coordinates", "one protocol")
    assert xy.title.startswith("Table 3a, gear, the paper's input") and xy.notes[-1] == "one protocol"
    assert xy.rows[0][1] == mcrl[1]  # the paper's MCRL row beside mcrl_xy


def test_two_workers_give_the_bytes_one_worker_gives(warm_server, monkeypatch):
    """Each run depends on its job and the thread count only, never on which worker ran it or when, nor on
    whether the worker was spawned or forked by `make repro`'s warm server."""
    import torch

    from toolpath.models.training.replicates import run_all
    from toolpath.pipeline.warm import POOL_ENV

    rng = np.random.default_rng(0)
    windows = rng.normal(size=(48, 50, 2)).cumsum(axis=1).astype(np.float32)
    labels = rng.integers(1, 5, 48)
    parts = {s: (windows[k::3], labels[k::3]) for k, s in enumerate(("train", "val", "test"))}
    programs = {s: np.arange(16) % 4 for s in parts}
    network = {"_target_": "toolpath.models.MLP", "hidden": [8]}
    jobs = [Job("mlp", r, network, {"epochs": 1, "batch_size": 8, "seed": r, "schedule": "onecycle"}) for r in range(3)]
    results = {}
    for workers, pool in ((1, None), (2, None), (2, warm_server)):
        if pool is not None:
            monkeypatch.setenv(POOL_ENV, str(pool))  # as in a stage the warm server runs
        outcomes = sorted(run_all(jobs, {"": parts}, {"": programs}, workers=workers, threads=1),
                          key=lambda o: o.job.replicate)
        results[workers, pool] = [(o.metrics["test"]["loss"], o.checkpoint["state_dict"]) for o in outcomes]
    for other in ((2, None), (2, warm_server)):
        for (loss1, state1), (loss2, state2) in zip(results[1, None], results[other], strict=True):
            assert loss1 == loss2 and all(torch.equal(state1[k], state2[k]) for k in state1)


def test_the_best_learned_model_is_chosen_on_validation_never_the_rule_or_a_degenerate_one():
    def seeds(val_f1, test_f1, degenerate=0):
        return {"degenerate": degenerate, "replicates": 3, "val": {"f1": {"mean": val_f1}},
                "test": {"f1": {"mean": test_f1}}}

    summaries = {"rule": seeds(1.0, 1.0), "lstm": seeds(0.90, 0.99), "mcrl": seeds(0.95, 0.90),
                 "cnn": seeds(0.99, 0.99, degenerate=3)}
    assert best_learned(summaries) == "mcrl"  # best on validation, though the LSTM is ahead on test
    summaries["cnn"]["degenerate"] = 2  # one learned seed of three: scored on it
    assert best_learned(summaries) == "cnn"
    assert best_learned({"a": seeds(0.9, 0.5), "b": seeds(0.9, 0.6)}) == "a"  # a tie: the first name
    assert best_learned({"rule": seeds(1.0, 1.0)}) is None


def test_a_training_process_runs_deterministic_kernels_without_loading_the_compiler():
    import subprocess
    import sys

    probe = ("import sys, torch\n"
             "from toolpath.models.training.replicates import deterministic_torch\n"
             "deterministic_torch(1)\n"
             "print(torch.are_deterministic_algorithms_enabled(),"
             " torch.is_deterministic_algorithms_warn_only_enabled(),"
             " torch.get_num_threads(), 'torch._inductor' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "False", "1", "False"]
