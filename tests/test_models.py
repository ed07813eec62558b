"""Every model: shapes, gradients, seeded determinism, torch.export; MCRL's sizes; the rule; inputs."""

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from sklearn.base import clone
from sklearn.metrics import accuracy_score, f1_score

from conftest import REPO
from toolpath.geometry import local_curvature
from toolpath.geometry.labels import categorize
from toolpath.models import (
    LocalCurvatureRule,
    build,
    is_learned,
    prepare,
    random_reversal,
    random_rotation_reflection,
)
from toolpath.models.inputs import Prepare, turning_features
from toolpath.models.registry import parameter_count
from toolpath.models.training import TorchClassifier

# the composed configs (conf/model/rule.yaml takes its bounds from conf/label)
CONFIGS = OmegaConf.to_container(OmegaConf.load(REPO / "params.yaml").models, resolve=True)
LEARNED = [name for name, config in CONFIGS.items() if is_learned(config)]


def windows(n=7, seed=0):
    return torch.randn(n, 50, 2, generator=torch.Generator().manual_seed(seed)).cumsum(dim=1)


@pytest.mark.parametrize("name", LEARNED)
@pytest.mark.parametrize("batch", [1, 7])
def test_maps_windows_to_four_logits_and_backpropagates(name, batch):
    torch.manual_seed(0)
    net = build(CONFIGS[name]).train()
    out = net(windows(batch))
    assert out.shape == (batch, 4) and out.dtype == torch.float32
    if batch > 1:  # BatchNorm needs more than one sample in training mode
        out.sum().backward()
        grads = [p.grad for p in net.parameters() if p.requires_grad]
        assert all(g is not None for g in grads) and any(g.abs().sum() > 0 for g in grads)


@pytest.mark.parametrize("name", LEARNED)
def test_seeded_build_is_deterministic(name):
    outs = []
    for _ in range(2):
        torch.manual_seed(123)
        outs.append(build(CONFIGS[name]).eval()(windows()))
    assert torch.equal(outs[0], outs[1])


@pytest.mark.parametrize("name", LEARNED)
def test_traces_with_torch_export(name):
    net = build(CONFIGS[name]).eval()
    x = windows(7)
    exported = torch.export.export(net, (x,))
    assert torch.allclose(exported.module()(x), net(x), atol=1e-5)


def test_parameter_counts_are_within_a_factor_of_two_of_mcrl_for_modern_baselines():
    counts = {n: parameter_count(build(CONFIGS[n])) for n in LEARNED}
    for name in ("convmixer", "convnext", "maxvit"):
        assert counts["mcrl"] / 2 <= counts[name] <= counts["mcrl"] * 2, (name, counts)


def test_mcrl_intermediate_shapes_match_the_text():
    net = build(CONFIGS["mcrl"]).eval()
    seen = {}

    def record(key, use_input):
        def hook(module, inputs, output):
            seen[key] = inputs[0].shape if use_input else output.shape
        return hook

    net.pool.register_forward_hook(record("pool", False))
    net.cnn_fc.register_forward_hook(record("flat", True))
    h1, h2, h3, h4 = net.features(windows(3))
    assert seen["pool"] == (3, 32, 15)  # 15 x 32 after max-pooling
    assert seen["flat"] == (3, 480)
    assert h1.shape == (3, 16) and h2.shape == (3, 512) and h3.shape == (3, 64) and h4.shape == (3, 32)
    assert [b.points for b in net.branches] == [50, 30, 20, 10]


def test_mcrl_fused_with_branch_outputs_feeds_each_branch_the_previous_class_probabilities():
    """fuse: output (the text's "fused with the MLP / CNN / RNN output" read as the 4-node softmax):
    the next branch's input is 2 channels plus 4 probabilities that sum to 1 at every step."""
    net = build({**CONFIGS["mcrl"], "fuse": "output"}).eval()
    seen = {}

    def record(key):
        def hook(module, inputs, output):
            # the first RNN takes (sequence, context) and fuses them itself
            seen[key] = inputs[0] if len(inputs) == 1 else torch.cat(
                [inputs[0], inputs[1][:, None, :].expand(-1, inputs[0].shape[1], -1)], dim=2)
        return hook

    for key, module in (("conv", net.conv), ("rnn", net.rnns[0]), ("lstm", net.lstms[0])):
        module.register_forward_hook(record(key))
    assert net(windows(3)).shape == (3, 4)
    assert seen["conv"].shape == (3, 6, 30) and seen["rnn"].shape == (3, 20, 6) and seen["lstm"].shape == (3, 10, 6)
    assert torch.allclose(seen["rnn"][..., 2:].sum(-1), torch.ones(3, 20))
    assert parameter_count(net) < parameter_count(build({**CONFIGS["mcrl"], "fuse": "hidden"}))
    with pytest.raises(ValueError, match="fuse"):
        build({**CONFIGS["mcrl"], "fuse": "sum"})


def test_context_rnn_is_the_rnn_of_the_fused_input():
    """ContextRNN computes the context's share of the input projection once: the same function as
    nn.RNN on [sequence | context] at every step, with the same parameters (checkpoints load both ways)."""
    from toolpath.models.mcrl import ContextRNN, _fuse

    torch.manual_seed(0)
    fast, plain = ContextRNN(2, 5, 7), torch.nn.RNN(7, 7, batch_first=True)
    plain.load_state_dict(fast.state_dict())
    seq, context = torch.randn(4, 9, 2), torch.randn(4, 5)
    assert torch.allclose(fast(seq, context), plain(_fuse(seq, context))[0], atol=1e-6)
    # one step by hand: h1 = tanh(W_ih [s1 | c] + b_ih + b_hh), from h0 = 0
    with torch.no_grad():
        for p in fast.parameters():
            p.fill_(0.1)
    one = fast(torch.ones(1, 1, 2), torch.ones(1, 5))
    assert torch.allclose(one, torch.full((1, 1, 7), float(np.tanh(0.1 * 7 + 0.2))))


def test_input_preparation_keeps_local_curvature_and_normalises():
    x = windows(20) * 37.0 + 500.0
    prepared = prepare(x)
    assert np.allclose(local_curvature(prepared.double().numpy()), local_curvature(x.double().numpy()), atol=1e-4)
    assert torch.allclose(prepared.mean(dim=1), torch.zeros(20, 2), atol=1e-5)
    assert torch.allclose(prepared.pow(2).sum(2).mean(1), torch.ones(20), atol=1e-5)
    assert torch.isfinite(prepare(torch.zeros(2, 50, 2))).all()  # degenerate window: no NaN


def test_turning_features_by_hand():
    """Square corner: one right-angle turn (1, +1) at the corner; straight line: zeros; circle: a
    constant turn of 2 pi / k per point; a repeated point counts as no turn (the rule's convention)."""
    corner = torch.tensor([[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 2.0]]])
    f = turning_features(corner)
    assert f.shape == (1, 5, 2)
    assert torch.allclose(f[0], torch.tensor([[0, 0], [0, 0], [1.0, 1.0], [0, 0], [0, 0]]))
    line = torch.stack([torch.linspace(0, 9, 50, dtype=torch.float64),
                        torch.linspace(3, -6, 50, dtype=torch.float64)], dim=1)[None]
    assert torch.count_nonzero(turning_features(line).abs() > 1e-6) == 0
    k = 40
    t = torch.arange(50, dtype=torch.float64) * 2 * torch.pi / k
    circle = torch.stack([torch.cos(t), torch.sin(t)], dim=1)[None] * 7.0
    f = turning_features(circle)[0, 1:-1]
    assert torch.allclose(f[:, 0], torch.full((48,), 1 - np.cos(2 * np.pi / k), dtype=torch.float64))
    assert torch.allclose(f[:, 1], torch.full((48,), np.sin(2 * np.pi / k), dtype=torch.float64))  # CCW: +
    repeated = torch.tensor([[[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0]]])
    assert torch.count_nonzero(turning_features(repeated)) == 0


def test_turning_features_sum_to_local_curvature_at_any_scale_and_rotation():
    x = windows(20).double()
    moved = random_rotation_reflection(x, torch.Generator().manual_seed(2)) * 37.0 + 500.0
    assert np.allclose(turning_features(x)[..., 0].sum(1).numpy(), local_curvature(x.numpy()), atol=1e-9)
    assert torch.allclose(turning_features(moved)[..., 0], turning_features(x)[..., 0], atol=1e-9)
    with pytest.raises(ValueError, match="inputs must be one of"):
        Prepare("raw")


@pytest.mark.parametrize("inputs", ["turning", "coordinates"])
def test_prepare_scales_each_feature_and_lays_it_out_either_way(inputs):
    """Each feature times its scale, bit for bit what scaling the stacked features gives, and the
    channels-first layout is the transpose of the default one (the convolutional models read it)."""
    x = windows(16) * 5.0
    layer = Prepare(inputs, stem_width=0)  # the stem after the scaling: tests/test_stem.py
    layer.fit_scale(x)
    assert not torch.equal(layer.scale, torch.ones(2))
    features = turning_features(x) if inputs == "turning" else prepare(x)
    assert torch.equal(layer(x), features * layer.scale)
    assert torch.equal(layer(x, channels_first=True), layer(x).transpose(1, 2))


@pytest.mark.parametrize("name", ["cnn", "convmixer", "convnext", "maxvit"])
def test_exported_input_preparation_belongs_to_its_module(name):
    """``qat.float_modules`` finds the input preparation by module: every op computing it must be
    attributed to ``prepare`` in the exported graph, the channels-first call included."""
    program = torch.export.export(build(CONFIGS[name]).eval(), (windows(4),))
    buffer = next(p for p, b in program.graph_signature.inputs_to_buffers.items() if b == "prepare.scale")
    scale = next(n for n in program.graph.nodes if n.name == buffer)
    readers = [*scale.users, *(u for n in scale.users for u in n.users)]  # select -> mul
    assert any("mul" in str(n.target) for n in readers)
    for node in readers:
        assert any(path == "prepare" for path, _ in node.meta["nn_module_stack"].values()), node


def test_rotation_reflection_augmentation_keeps_local_curvature():
    x = windows(30).double()
    aug = random_rotation_reflection(x, torch.Generator().manual_seed(1))
    assert not torch.allclose(aug, x)
    assert np.allclose(local_curvature(aug.numpy()), local_curvature(x.numpy()), atol=1e-8)


def test_reversal_augmentation_keeps_local_curvature_and_reverses_about_half():
    x = windows(40).double()
    aug = random_reversal(x, torch.Generator().manual_seed(3))
    reversed_ = torch.all(aug == x.flip(1), dim=(1, 2))
    assert 5 < int(reversed_.sum()) < 35 and torch.all(reversed_ | torch.all(aug == x, dim=(1, 2)))
    assert np.allclose(local_curvature(aug.numpy()), local_curvature(x.numpy()), atol=1e-12)


def test_rule_agrees_with_the_labeller_and_speaks_sklearn():
    rng = np.random.default_rng(4)
    X = rng.normal(size=(300, 50, 2)) * rng.uniform(0.01, 1.0, size=(300, 1, 2))
    X = np.cumsum(X + np.array([1.0, 0.0]), axis=1)
    expected = categorize(local_curvature(X))
    rule = build(CONFIGS["rule"])
    assert rule.fit(X) is rule
    assert np.array_equal(rule.predict(X), expected)
    assert np.array_equal(rule.predict(X.reshape(300, 100)), expected)  # flattened input too
    proba = rule.predict_proba(X)
    assert proba.shape == (300, 4) and np.array_equal(proba.sum(1), np.ones(300))
    assert rule.score(X, expected) == 1.0
    assert set(np.unique(expected)) >= {1, 2}
    assert isinstance(clone(rule), LocalCurvatureRule)
    with pytest.raises(ValueError, match="expected windows"):
        rule.predict(np.zeros((3, 7)))


def easy_split(n, seed):
    """Straight lines (category 1) against zig-zags (category 4)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, 50)
    X, y = [], []
    for k in range(n):
        line = np.column_stack([t, rng.uniform(-1, 1) * t])
        if k % 2:
            line[:, 1] += 0.05 * (np.arange(50) % 2)
        X.append(line * rng.uniform(1, 50) + rng.normal(size=2) * 20)
        y.append(4 if k % 2 else 1)
    return np.array(X, dtype=np.float32), np.array(y)


def test_torch_classifier_learns_an_easy_split_and_works_with_sklearn_metrics():
    X, y = easy_split(400, 0)
    Xt, yt = easy_split(100, 1)
    clf = TorchClassifier(network=CONFIGS["mlp"], settings={"lr": 3e-3, "epochs": 16, "batch_size": 32, "seed": 0})
    clf.fit(X, y, Xt, yt)
    pred = clf.predict(Xt)
    assert accuracy_score(yt, pred) > 0.9  # chance is 0.5
    assert f1_score(yt, pred, average="macro", labels=[1, 4]) > 0.9
    assert clf.predict_proba(Xt).shape == (100, 4) and np.allclose(clf.predict_proba(Xt).sum(1), 1)
    assert len(clf.history_) == 16 and clf.history_[-1].val_accuracy > 0.9
    again = clone(clf).fit(X, y, Xt, yt)
    assert np.array_equal(again.predict_proba(Xt), clf.predict_proba(Xt))  # same seed, same result


def test_schedule_is_a_staircase_per_optimiser_step():
    X, y = easy_split(64, 0)
    clf = TorchClassifier(network=CONFIGS["mlp"], settings={"lr": 1.0e-2, "decay_rate": 0.5, "decay_steps": 4,
                                                            "batch_size": 16, "epochs": 3, "seed": 0}).fit(X, y)
    assert [r.lr for r in clf.history_] == pytest.approx([1e-2, 5e-3, 2.5e-3])  # 4 steps per epoch


def test_metrics_equal_sklearn_on_a_hand_made_case():
    from sklearn.metrics import f1_score as f1
    from sklearn.metrics import precision_score, recall_score, roc_auc_score

    from toolpath.models.training.metrics import classification_metrics

    y = np.array([1, 1, 2, 2, 3, 4, 4, 4])
    proba = np.array([[.7, .1, .1, .1], [.2, .5, .2, .1], [.1, .8, .05, .05], [.6, .2, .1, .1],
                      [.1, .1, .7, .1], [.05, .05, .1, .8], [.1, .1, .2, .6], [.1, .1, .5, .3]])
    m = classification_metrics(y, proba)
    pred = np.array([1, 2, 2, 1, 3, 4, 4, 3])
    assert m["accuracy"] == 5 / 8
    assert m["precision"] == pytest.approx(precision_score(y, pred, average="macro"))
    assert m["recall"] == pytest.approx(recall_score(y, pred, average="macro"))
    assert m["f1"] == pytest.approx(f1(y, pred, average="macro"))
    assert m["auc"] == pytest.approx(roc_auc_score(y, proba, multi_class="ovr", average="macro"))
    assert m["loss"] == pytest.approx(-np.mean(np.log(proba[np.arange(8), y - 1])))  # Eq. 29
    assert m["confusion"] == [[1, 1, 0, 0], [1, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 2]]
    assert m["per_class"]["3"]["support"] == 1
    missing = classification_metrics(np.array([1, 1, 2]), np.array([[.9, .1, 0, 0], [.2, .8, 0, 0], [.3, .7, 0, 0]]))
    assert missing["per_class"]["4"]["auc"] is None and missing["auc"] is not None
