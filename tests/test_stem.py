"""The learned first layers of the models on coordinates (models.inputs.DifferenceStem), against
hand-computed cases: a straight line, a square corner, a translated and rescaled copy."""

import math

import pytest
import torch

from toolpath.models.inputs import DifferenceConv, DifferenceStem, Prepare, point_rms_norm


def polyline(points) -> torch.Tensor:
    return torch.tensor(points, dtype=torch.float64)[None]


def stem(seed=0) -> DifferenceStem:
    torch.manual_seed(seed)
    return DifferenceStem(8).double().eval()


def test_difference_kernel_sums_to_zero_and_ignores_a_shift():
    conv = DifferenceConv(2, 5, 3).double()
    x = torch.randn(3, 2, 20, dtype=torch.float64)
    assert torch.allclose(conv(x + torch.tensor([4.0, -7.0], dtype=torch.float64)[None, :, None]), conv(x))
    ones = torch.ones(1, 2, 3, dtype=torch.float64)  # a constant signal: only the bias is left
    assert torch.allclose(conv(ones), conv.bias.detach()[None, :, None])


def test_point_rms_norm_by_hand():
    x = torch.tensor([[[3.0], [4.0]]])  # one point, two channels: RMS sqrt(12.5)
    assert torch.allclose(point_rms_norm(x, eps=0.0), torch.tensor([[[3.0], [4.0]]]) / math.sqrt(12.5))
    assert torch.allclose(point_rms_norm(1e-3 * x), point_rms_norm(x), atol=1e-6)  # the size drops out


def test_a_straight_line_gives_the_same_output_at_every_point_whatever_its_spacing():
    spacing = torch.tensor([0.0, 0.1, 0.15, 0.45, 0.5, 1.3, 1.31, 2.0], dtype=torch.float64)
    line = torch.stack([spacing * 3.0, spacing * 4.0], dim=1)[None]  # uneven steps along one direction
    out = stem()(line.transpose(1, 2))[0]
    interior = out[:, 1:-1]
    assert torch.allclose(interior, interior[:, :1].expand_as(interior), atol=1e-9)
    assert torch.equal(out[:, 0], torch.zeros(2, dtype=torch.float64))  # the end points have no turn
    assert torch.equal(out[:, -1], torch.zeros(2, dtype=torch.float64))


def test_a_square_corner_changes_the_output_at_the_corner_only():
    corner = polyline([[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2], [3, 3]])  # 90 degrees at point 3
    straight = polyline([[0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [5, 0], [6, 0]])
    net = stem()
    a, b = net(corner.transpose(1, 2))[0], net(straight.transpose(1, 2))[0]
    changed = [i for i in range(1, 6) if not torch.allclose(a[:, i], b[:, i], atol=1e-9)]
    assert changed == [3]


def test_the_stem_is_blind_to_translation_and_scale_of_the_window():
    torch.manual_seed(1)
    x = torch.randn(4, 50, 2).cumsum(dim=1)
    layer = Prepare("coordinates").eval()
    assert layer.stem is not None and Prepare("coordinates", stem_width=0).stem is None
    assert Prepare("turning").stem is None
    assert torch.allclose(layer(x * 250.0 + 30.0), layer(x), atol=1e-5)
    assert torch.equal(layer(x, channels_first=True), layer(x).transpose(1, 2))


@pytest.mark.parametrize("width", [1, 16])
def test_the_stem_trains(width):
    net = DifferenceStem(width)
    out = net(torch.randn(2, 2, 10)).square().sum()
    out.backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in net.parameters())
