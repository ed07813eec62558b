"""The training loop's schedule, clipping, best-weight restore and input scaling; MCRL's resampling."""

import numpy as np
import pytest
import torch

from toolpath.models.inputs import Prepare, turning_features
from toolpath.models.mcrl import _Branch
from toolpath.models.training.loop import TrainSettings, fit_network


def _data(n=64, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 50, 2)).cumsum(axis=1).astype(np.float32)
    return X, rng.integers(0, 4, n)


def _mlp():
    from toolpath.models import MLP

    torch.manual_seed(0)
    return MLP(hidden=(8,))


def test_onecycle_warms_up_then_decays_over_the_steps_actually_run():
    X, y = _data()
    history = fit_network(_mlp(), X, y, TrainSettings(lr=1e-2, batch_size=16, epochs=4, schedule="onecycle",
                                                      warmup=0.5, seed=1))
    lrs = [r.lr for r in history]  # at each epoch's start: 4 steps per epoch, peak after 8 of 16
    assert lrs[0] == pytest.approx(1e-2 / 25)  # torch's default initial division
    assert lrs[2] == pytest.approx(1e-2, rel=0.05) and lrs[1] < lrs[2] and lrs[3] < lrs[2]  # peak at step 7


def test_the_staircase_of_table2_is_kept():
    X, y = _data()
    history = fit_network(_mlp(), X, y, TrainSettings(lr=1e-2, batch_size=16, epochs=3, decay_rate=0.5,
                                                      decay_steps=4, seed=1))
    assert [r.lr for r in history] == pytest.approx([1e-2, 5e-3, 2.5e-3])


def test_an_unknown_schedule_is_refused():
    X, y = _data()
    with pytest.raises(ValueError, match="schedule must be one of"):
        fit_network(_mlp(), X, y, TrainSettings(schedule="cosine", epochs=1))


def test_clipping_bounds_every_update(monkeypatch):
    X, y = _data()
    norms = []
    original = torch.nn.utils.clip_grad_norm_

    def spy(parameters, max_norm, *a, **k):
        parameters = list(parameters)
        original(parameters, max_norm, *a, **k)
        norms.append(float(torch.linalg.vector_norm(torch.stack([p.grad.norm() for p in parameters]))))

    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", spy)
    fit_network(_mlp(), X * 100, y, TrainSettings(lr=1e-3, batch_size=16, epochs=1, clip_grad_norm=0.01, seed=2))
    assert len(norms) == 4 and max(norms) <= 0.01 + 1e-6


def test_restore_best_ends_on_the_lowest_validation_loss_epoch():
    X, y = _data()
    Xv, yv = _data(32, seed=5)
    net = _mlp()
    history = fit_network(net, X, y, TrainSettings(lr=5e-2, batch_size=8, epochs=6, restore_best=True, seed=3),
                          Xv, yv)
    best = min(r.val_loss for r in history)
    with torch.no_grad():
        logits = net(torch.as_tensor(Xv))
    final = float(torch.nn.functional.cross_entropy(logits, torch.as_tensor(yv)))
    assert final == pytest.approx(best, rel=1e-5)


def test_input_scale_brings_each_feature_to_unit_rms_and_is_saved_with_the_weights():
    X, y = _data()
    net = _mlp()
    fit_network(net, X, y, TrainSettings(epochs=1, batch_size=64, normalise_inputs=True, seed=0))
    features = net.prepare(torch.as_tensor(X))
    assert features.pow(2).mean(dim=(0, 1)).sqrt() == pytest.approx(torch.ones(2), rel=1e-5)
    assert "prepare.scale" in net.state_dict()
    plain = Prepare()
    assert torch.equal(plain(torch.as_tensor(X)), turning_features(torch.as_tensor(X)))  # 1 until fitted


def test_area_resampling_keeps_a_spike_that_interpolation_drops():
    """50 -> 10 points: linear interpolation (align_corners) reads positions 0, 5.44, 10.9, ...; a turn at
    point 3 falls between two read points' neighbours and vanishes, while the area mean keeps it (1/5 of
    it lands in the first output).  The attention is bypassed to see the resampled sequence."""
    x = torch.zeros(1, 50, 2)
    x[0, 3, 0] = 1.0
    for mode, expected in (("area", 0.2), ("linear", 0.0)):
        branch = _Branch(10, 4, mode)
        with torch.no_grad():
            branch.linear.weight.copy_(torch.eye(2))
            branch.linear.bias.zero_()
        branch.attention = torch.nn.Identity()
        with torch.no_grad():
            out = branch(x)
        assert out.shape == (1, 10, 2) and float(out[0, :, 0].sum()) == pytest.approx(expected, abs=1e-7)
