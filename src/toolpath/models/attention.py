"""ReLU linear attention (Sec. 5.1.1): phi = ReLU on queries and keys, cost linear in sequence length."""

from __future__ import annotations

from torch import Tensor, nn


class ReLULinearAttention(nn.Module):
    """``out_i = phi(q_i) . sum_j phi(k_j) v_j^T / (phi(q_i) . sum_j phi(k_j) + eps)``, plus a residual.

    Queries and keys are projected to ``width`` features, values keep the ``channels`` of the
    input, so the output has the input's shape (B, L, channels).  The normaliser is clamped away
    from zero: an all-zero ReLU row would otherwise divide by ``eps`` alone and, under fake
    quantisation, blow up (seen with FX QAT on this machine kind).
    """

    def __init__(self, channels: int, width: int = 16, eps: float = 1e-4) -> None:
        super().__init__()
        self.query = nn.Linear(channels, width)
        self.key = nn.Linear(channels, width)
        self.value = nn.Linear(channels, channels)
        self.eps = eps

    def forward(self, x: Tensor) -> Tensor:
        q = self.query(x).relu()
        k = self.key(x).relu()
        v = self.value(x)
        kv = k.transpose(1, 2) @ v  # (B, width, channels): one pass over the sequence
        norm = (q @ k.sum(dim=1, keepdim=True).transpose(1, 2)).clamp_min(self.eps)  # (B, L, 1)
        return x + (q @ kv) / norm
