"""1-D adaptations of ConvMixer, ConvNeXt and MaxViT over the 50-point sequence (Table 3 rows).

The papers define 2-D image models; here every 2-D operation becomes its 1-D counterpart over the
window's points, channels carry the coordinates, and the sizes are chosen to land within a factor
of 2 of MCRL's parameter count (see ``python -m toolpath.models``).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from toolpath.models.inputs import Prepare


class ConvMixer1d(nn.Module):
    """ConvMixer (Trockman & Kolter 2022) in 1-D.

    Patch embedding ``Conv1d(2, dim, patch, stride=patch)`` -> GELU -> BatchNorm; ``depth`` blocks of
    [residual(depthwise Conv1d(kernel, 'same') -> GELU -> BatchNorm) -> pointwise Conv1d -> GELU ->
    BatchNorm]; global average pooling; linear head.
    """

    def __init__(self, dim: int = 192, depth: int = 8, kernel: int = 9, patch: int = 2, classes: int = 4,
                 inputs: str = "turning") -> None:
        super().__init__()
        self.prepare = Prepare(inputs)
        self.embed = nn.Sequential(nn.Conv1d(2, dim, patch, stride=patch), nn.GELU(), nn.BatchNorm1d(dim))
        self.depthwise = nn.ModuleList(
            nn.Sequential(nn.Conv1d(dim, dim, kernel, groups=dim, padding="same"), nn.GELU(), nn.BatchNorm1d(dim))
            for _ in range(depth))
        self.pointwise = nn.ModuleList(
            nn.Sequential(nn.Conv1d(dim, dim, 1), nn.GELU(), nn.BatchNorm1d(dim)) for _ in range(depth))
        self.head = nn.Linear(dim, classes)

    def forward(self, x: Tensor) -> Tensor:
        h = self.embed(self.prepare(x, channels_first=True))
        for depthwise, pointwise in zip(self.depthwise, self.pointwise, strict=True):
            h = pointwise(h + depthwise(h))
        return self.head(h.mean(dim=2))


class _ConvNeXtBlock(nn.Module):
    """Depthwise Conv1d 7 -> LayerNorm -> Linear 4x -> GELU -> Linear -> layer scale, residual."""

    def __init__(self, dim: int, layer_scale: float = 1e-6) -> None:
        super().__init__()
        self.dwconv = nn.Conv1d(dim, dim, 7, padding=3, groups=dim)
        self.norm = nn.LayerNorm(dim)
        self.mlp = nn.Sequential(nn.Linear(dim, 4 * dim), nn.GELU(), nn.Linear(4 * dim, dim))
        self.gamma = nn.Parameter(layer_scale * torch.ones(dim))

    def forward(self, x: Tensor) -> Tensor:  # x: (B, C, L)
        h = self.dwconv(x).transpose(1, 2)
        h = self.gamma * self.mlp(self.norm(h))
        return x + h.transpose(1, 2)


class _ChannelNorm(nn.Module):
    """LayerNorm over channels of a (B, C, L) tensor."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(dim)

    def forward(self, x: Tensor) -> Tensor:
        return self.norm(x.transpose(1, 2)).transpose(1, 2)


class ConvNeXt1d(nn.Module):
    """ConvNeXt (Liu et al. 2022) in 1-D.

    Stem ``Conv1d(2, d0, 2, stride 2)`` + LayerNorm (50 -> 25 points); stages of ConvNeXt blocks,
    with LayerNorm + ``Conv1d(k=2, stride 2)`` down-sampling between stages (25 -> 12 -> 6);
    global average pooling, LayerNorm, linear head.  Stochastic depth is left out (small data).
    """

    def __init__(self, dims: tuple[int, ...] = (48, 96, 144), depths: tuple[int, ...] = (2, 2, 2),
                 classes: int = 4, inputs: str = "turning") -> None:
        super().__init__()
        self.prepare = Prepare(inputs)
        self.stem = nn.Sequential(nn.Conv1d(2, dims[0], 2, stride=2), _ChannelNorm(dims[0]))
        stages: list[nn.Module] = []
        for i, (dim, depth) in enumerate(zip(dims, depths, strict=True)):
            if i > 0:
                stages.append(nn.Sequential(_ChannelNorm(dims[i - 1]), nn.Conv1d(dims[i - 1], dim, 2, stride=2)))
            stages.extend(_ConvNeXtBlock(dim) for _ in range(depth))
        self.stages = nn.Sequential(*stages)
        self.norm = nn.LayerNorm(dims[-1])
        self.head = nn.Linear(dims[-1], classes)

    def forward(self, x: Tensor) -> Tensor:
        h = self.stages(self.stem(self.prepare(x, channels_first=True)))
        return self.head(self.norm(h.mean(dim=2)))


class _MBConv(nn.Module):
    """Inverted residual: 1x1 expand -> GELU -> depthwise 3 -> GELU -> 1x1 project, BatchNorm, residual."""

    def __init__(self, dim: int, expand: int = 4) -> None:
        super().__init__()
        hidden = dim * expand
        self.net = nn.Sequential(
            nn.BatchNorm1d(dim), nn.Conv1d(dim, hidden, 1), nn.GELU(),
            nn.Conv1d(hidden, hidden, 3, padding=1, groups=hidden), nn.GELU(), nn.Conv1d(hidden, dim, 1))

    def forward(self, x: Tensor) -> Tensor:
        return x + self.net(x)


class _PartitionAttention(nn.Module):
    """Self-attention inside groups of tokens, then an MLP (pre-norm, residual).

    ``grid=False`` groups contiguous tokens (block attention: local windows of ``size``);
    ``grid=True`` groups tokens ``size`` apart (grid attention: a dilated, global pattern).
    """

    def __init__(self, dim: int, heads: int, size: int, grid: bool) -> None:
        super().__init__()
        self.size, self.grid = size, grid
        self.norm1 = nn.LayerNorm(dim)
        self.attn = nn.MultiheadAttention(dim, heads, batch_first=True)
        self.norm2 = nn.LayerNorm(dim)
        self.mlp = nn.Sequential(nn.Linear(dim, 4 * dim), nn.GELU(), nn.Linear(4 * dim, dim))

    def forward(self, x: Tensor) -> Tensor:  # x: (B, L, C), L divisible by size
        b, length, c = x.shape
        groups = length // self.size
        # grid: token i joins group i % groups; block: token i joins group i // size
        parts = x.reshape(b, self.size, groups, c).transpose(1, 2) if self.grid else x.reshape(b, groups, self.size, c)
        parts = parts.reshape(b * groups, self.size, c)
        h = self.norm1(parts)
        parts = parts + self.attn(h, h, h, need_weights=False)[0]
        parts = parts + self.mlp(self.norm2(parts))
        parts = parts.reshape(b, groups, self.size, c)
        if self.grid:
            parts = parts.transpose(1, 2)
        return parts.reshape(b, length, c)


class MaxViT1d(nn.Module):
    """MaxViT (Tu et al. 2022) in 1-D.

    Stem ``Conv1d(2, dim, 2 patch - 1, stride patch, padding patch - 1)`` (50 -> ceil(50 / patch)
    tokens: 25 at patch 2, 10 at patch 5) plus a learned position embedding; ``depth`` MaxViT blocks
    of MBConv -> block attention (windows of ``partition`` neighbouring tokens) -> grid attention
    (groups of ``partition`` tokens spread evenly over the sequence); global average pooling,
    LayerNorm, head.
    """

    def __init__(self, dim: int = 64, depth: int = 3, heads: int = 4, partition: int = 5, window: int = 50,
                 classes: int = 4, inputs: str = "turning", patch: int = 2) -> None:
        super().__init__()

        self.prepare = Prepare(inputs)
        self.stem = nn.Conv1d(2, dim, 2 * patch - 1, stride=patch, padding=patch - 1)
        tokens = -(-window // patch)
        if tokens % partition:
            raise ValueError(f"{tokens} tokens do not split into partitions of {partition}")
        self.position = nn.Parameter(torch.zeros(1, tokens, dim))
        self.mbconv = nn.ModuleList(_MBConv(dim) for _ in range(depth))
        self.block = nn.ModuleList(_PartitionAttention(dim, heads, partition, grid=False) for _ in range(depth))
        self.grid = nn.ModuleList(_PartitionAttention(dim, heads, partition, grid=True) for _ in range(depth))
        self.norm = nn.LayerNorm(dim)
        self.head = nn.Linear(dim, classes)

    def forward(self, x: Tensor) -> Tensor:
        h = F.gelu(self.stem(self.prepare(x, channels_first=True)))
        h = h.transpose(1, 2) + self.position
        for mbconv, block, grid in zip(self.mbconv, self.block, self.grid, strict=True):
            h = mbconv(h.transpose(1, 2)).transpose(1, 2)
            h = grid(block(h))
        return self.head(self.norm(h.mean(dim=1)))
