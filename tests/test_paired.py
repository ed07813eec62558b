"""Paired comparisons (issue 39): model A minus model B on the same test programs, resampling programs
and seeds together; the point estimate is scikit-learn's seed-mean difference."""

import numpy as np
from sklearn.metrics import accuracy_score, confusion_matrix, f1_score

from toolpath.models.training.metrics import DEGENERATE, paired_bootstrap
from toolpath.models.training.replicates import Job, Outcome, learned_predictions, paired, saved_predictions

RNG = np.random.default_rng(0)
Y = RNG.integers(1, 5, 400)
PROGRAMS = np.repeat(np.arange(40), 10)


def noisy(share_right: float, seeds: int = 3, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.where(rng.random((seeds, len(Y))) < share_right, Y, rng.integers(1, 5, (seeds, len(Y))))


def test_the_point_estimate_is_the_difference_of_seed_means_by_scikit_learn():
    a, b = noisy(0.9, seed=1), noisy(0.6, seed=2)
    result = paired_bootstrap(a, b, Y, PROGRAMS, seed=3)
    acc = np.mean([accuracy_score(Y, p) for p in a]) - np.mean([accuracy_score(Y, p) for p in b])
    f1 = np.mean([f1_score(Y, p, average="macro") for p in a]) - np.mean([f1_score(Y, p, average="macro") for p in b])
    assert np.isclose(result["accuracy"]["difference"], acc) and np.isclose(result["f1"]["difference"], f1)
    assert result["accuracy"]["low"] < acc < result["accuracy"]["high"]
    assert result["accuracy"]["verdict"] == "better" and result["f1"]["verdict"] == "better"
    assert paired_bootstrap(b, a, Y, PROGRAMS, seed=3)["accuracy"]["verdict"] == "worse"
    assert result["programs"] == 40 and result["seeds"] == [3, 3]


def test_a_model_against_its_own_seeds_shows_no_difference():
    a = noisy(0.8, seed=4)
    result = paired_bootstrap(a, a[::-1], Y, PROGRAMS, seed=5)
    assert result["accuracy"]["difference"] == 0.0
    assert result["accuracy"]["low"] < 0 < result["accuracy"]["high"]
    assert result["accuracy"]["verdict"] == result["f1"]["verdict"] == "no difference shown"


def test_pairing_narrows_the_interval_when_both_models_fail_on_the_same_programs():
    """Half the programs are hard for both models: a paired draw moves both figures together."""
    hard = PROGRAMS < 20
    a = np.where(hard, 1 + (Y % 4), Y)[None].repeat(3, 0)  # wrong on every hard window
    b = a.copy()
    b[:, ~hard & (np.arange(len(Y)) % 25 == 0)] = 1 + (Y[~hard & (np.arange(len(Y)) % 25 == 0)] % 4)
    result = paired_bootstrap(a, b, Y, PROGRAMS, seed=6)
    assert result["accuracy"]["verdict"] == "better"  # a few windows apart, every draw
    assert result["accuracy"]["high"] - result["accuracy"]["low"] < 0.03


def outcome(model, replicate, predicted):
    correct = predicted == Y
    metrics = {"test": {"confusion": confusion_matrix(Y, predicted, labels=[1, 2, 3, 4]).tolist(),
                        "accuracy": correct.mean()}}
    return Outcome(Job(model, replicate, {}, {}), {}, metrics, [], 1.0, correct, 0.0, predicted)


def test_mcrl_meets_every_model_on_its_own_input_and_the_other_mcrl():
    runs = {m: [outcome(m, r, p) for r, p in enumerate(noisy(share, seed=k))]
            for k, (m, share) in enumerate([("mcrl", 0.9), ("mlp", 0.7), ("mcrl_xy", 0.9), ("cnn_xy", 0.9)])}
    runs["rnn_xy"] = [outcome("rnn_xy", r, np.ones_like(Y)) for r in range(3)]  # one class: degenerate
    inputs = {"mcrl": "turning", "mlp": "turning", "mcrl_xy": "coordinates", "cnn_xy": "coordinates",
              "rnn_xy": "coordinates"}
    learned = {m: learned_predictions(saved_predictions(r)) for m, r in runs.items()}
    assert learned["rnn_xy"] is None and learned["mcrl"].shape == (3, len(Y))
    result = paired(learned, ["mcrl", "mcrl_xy"], inputs, Y, PROGRAMS, lambda a, b: 0)
    assert set(result["mcrl"]) == {"mlp", "mcrl_xy"} and set(result["mcrl_xy"]) == {"cnn_xy", "rnn_xy", "mcrl"}
    assert result["mcrl"]["mlp"]["accuracy"]["verdict"] == "better"
    assert result["mcrl_xy"]["rnn_xy"] == {"verdict": DEGENERATE}


def test_the_logistic_reference_reads_each_input_and_separates_lines_from_zigzags():
    import pytest

    from conftest import easy_split
    from toolpath.models.linear import features, fit_logistic
    from toolpath.models.training.replicates import logistic_reference

    X, y = easy_split(96)
    assert features(X, "turning").shape == (96, 100) and features(X, "coordinates").shape == (96, 100)
    model = fit_logistic(X[:64], y[:64] + 1, "turning")
    assert (model.predict(features(X[64:], "turning")) == y[64:] + 1).all()  # a turn is the whole signal
    parts = {"train": (X[:48], y[:48] + 1), "val": (X[48:72], y[48:72] + 1), "test": (X[72:], y[72:] + 1)}
    summary = logistic_reference(parts, ["turning"], np.arange(24) % 6, seed=0)["turning"]
    assert summary["test"]["accuracy"]["mean"] == 1.0 and summary["degenerate"] == 0
    assert summary["accuracy_ci"]["programs"] == 6
    with pytest.raises(ValueError, match="inputs must be one of"):
        features(X, "angles")
