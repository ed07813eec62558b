"""MCRL: MLP, CNN, RNN and LSTM branches with ReLU linear attention (Li et al. 2024, Sec. 5.1.1).

The text fixes the branch structure; the choices it leaves open are made here:

* Each branch starts with its own ``Linear(2, 2)`` on the coordinates, then resamples the window
  to 50 / 30 / 20 / 10 points (the text's "downsamples"): by default by averaging each output's
  share of the input (``resample: area``), so that the turning terms the label sums all reach
  every branch; ``resample: linear`` interpolates instead (reads 20 of 50 points at 10); then a
  ReLU linear attention whose output keeps 2 channels (so branch 1 flattens to 100, as the text says), with a residual.
* "Fused with" the previous branch's output, broadcast along the sequence and concatenated as
  channels.  ``fuse: hidden`` reads "output" as that branch's last hidden vector (MLP 16, CNN 512,
  RNN 64); ``fuse: output`` as what the text calls each branch's output, its 4-node softmax.  The
  second keeps the recurrent branches' inputs 6 wide instead of 514 and 66: the 512-wide CNN vector
  repeated over 20 steps saturates the first RNN's tanh and costs most of the model's multiply-adds.
* The "3x3 convolution" on a sequence is a Conv1d with kernel 3, padding 1 (30 -> 30 -> pool 15).
  ReLU is applied functionally after the Conv1d (inductor's INT8 fusion mis-sizes Conv1d followed
  by an ``nn.ReLU`` module in torch 2.13 + torchao 0.18).
* The RNN / LSTM layers are separate single-layer modules (hidden sizes differ); tanh is their own
  activation; the last time step of the third layer feeds the head.
* The first RNN layer is a :class:`ContextRNN`: the fused context is the same at every step, so its
  share of the input projection is computed once per window instead of 20 times (with ``fuse:
  hidden`` that share was about 45 % of the model's multiply-adds).  Same parameters, same function
  as ``nn.RNN`` on the concatenated input (a test checks this), about half the inference time.
* Each branch ends in a 4-logit head (the text's softmax is folded into the cross-entropy); the
  four heads are concatenated and fused by ``Linear(16, 4)``.  :meth:`MCRL.branch_logits` exposes
  the heads for the optional auxiliary losses (config ``aux_loss_weight``, 0 by default).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from toolpath.models.attention import ReLULinearAttention
from toolpath.models.inputs import Prepare

RESAMPLING = ("area", "linear")
FUSIONS = ("hidden", "output")


class _Branch(nn.Module):
    """Linear transformation, resampling to ``points``, ReLU linear attention."""

    def __init__(self, points: int, attention_width: int, resample: str = "area") -> None:
        super().__init__()
        if resample not in RESAMPLING:
            raise ValueError(f"resample must be one of {RESAMPLING}, got {resample!r}")
        self.points, self.resample = points, resample
        self.linear = nn.Linear(2, 2)
        self.attention = ReLULinearAttention(2, attention_width)

    def forward(self, x: Tensor) -> Tensor:
        y = self.linear(x)
        if y.shape[1] != self.points:
            y = y.transpose(1, 2)
            # area: each output averages its share of the input, so every turning term counts;
            # linear interpolation to 10 points reads 20 of the 50 and drops a spike between them
            y = F.adaptive_avg_pool1d(y, self.points) if self.resample == "area" else \
                F.interpolate(y, size=self.points, mode="linear", align_corners=True)
            y = y.transpose(1, 2)
        return self.attention(y)


class ContextRNN(nn.RNN):
    """A one-layer tanh ``nn.RNN`` (batch first) whose input is a sequence fused with a per-window context.

    ``forward(seq, context)`` equals ``nn.RNN.forward(_fuse(seq, context))[0]``:
    ``h_t = tanh(W_s s_t + W_c c + b_ih + W_hh h_{t-1} + b_hh)`` with ``W_ih = [W_s | W_c]``, where the
    constant ``W_c c + b_ih + b_hh`` is computed once.  The recurrence is written out step by step,
    which ``torch.export`` unrolls into plain linear ops that a quantizer can take to INT8 (the fused
    RNN kernel has no INT8 form).  Parameter names are ``nn.RNN``'s, so checkpoints load either way.
    """

    def __init__(self, sequence_size: int, context_size: int, hidden_size: int) -> None:
        super().__init__(sequence_size + context_size, hidden_size, batch_first=True)
        self.sequence_size = sequence_size

    def forward(self, seq: Tensor, context: Tensor) -> Tensor:  # type: ignore[override]
        weight = self.weight_ih_l0
        constant = F.linear(context, weight[:, self.sequence_size:], self.bias_ih_l0) + self.bias_hh_l0
        driven = F.linear(seq, weight[:, : self.sequence_size]) + constant[:, None, :]
        h = seq.new_zeros(seq.shape[0], self.hidden_size)
        steps = []
        for t in range(seq.shape[1]):
            h = torch.tanh(driven[:, t] + F.linear(h, self.weight_hh_l0))
            steps.append(h)
        return torch.stack(steps, dim=1)


def _fuse(seq: Tensor, context: Tensor) -> Tensor:
    """Concatenate a (B, C) context to every step of a (B, L, D) sequence -> (B, L, D + C)."""
    return torch.cat([seq, context[:, None, :].expand(-1, seq.shape[1], -1)], dim=2)


class MCRL(nn.Module):
    """Input (B, 50, 2) float32 windows, output (B, 4) logits."""

    def __init__(self, attention_width: int = 16, mlp_hidden: tuple[int, ...] = (128, 64, 32, 16),
                 conv_channels: int = 32, cnn_hidden: int = 512, rnn_hidden: tuple[int, ...] = (128, 64, 64),
                 lstm_hidden: tuple[int, ...] = (64, 32, 32), dropout: float = 0.2, window: int = 50,
                 points: tuple[int, int, int, int] = (50, 30, 20, 10), classes: int = 4,
                 inputs: str = "turning", resample: str = "area", fuse: str = "hidden") -> None:
        super().__init__()
        if fuse not in FUSIONS:
            raise ValueError(f"fuse must be one of {FUSIONS}, got {fuse!r}")
        self.fuse = fuse
        self.prepare = Prepare(inputs)
        self.branches = nn.ModuleList(_Branch(p, attention_width, resample) for p in points)
        dims = [points[0] * 2, *mlp_hidden]
        self.mlp = nn.Sequential(*[m for a, b in zip(dims[:-1], dims[1:], strict=True)
                                   for m in (nn.Linear(a, b), nn.ReLU())])
        # what branch k + 1 is fused with: branch k's last hidden vector, or its 4-class output
        context = (mlp_hidden[-1], cnn_hidden, rnn_hidden[-1]) if fuse == "hidden" else (classes,) * 3
        self.conv = nn.Conv1d(2 + context[0], conv_channels, kernel_size=3, padding=1)
        self.pool = nn.MaxPool1d(2)
        self.dropout = nn.Dropout(dropout)
        self.cnn_fc = nn.Linear(conv_channels * (points[1] // 2), cnn_hidden)
        self.rnns = nn.ModuleList([ContextRNN(2, context[1], rnn_hidden[0]),
                                   *(nn.RNN(a, b, batch_first=True) for a, b in zip(rnn_hidden[:-1], rnn_hidden[1:],
                                                                                  strict=True))])
        lstm_in = [2 + context[2], *lstm_hidden[:-1]]
        self.lstms = nn.ModuleList(nn.LSTM(a, b, batch_first=True) for a, b in zip(lstm_in, lstm_hidden, strict=True))
        self.heads = nn.ModuleList(nn.Linear(d, classes) for d in (mlp_hidden[-1], cnn_hidden, rnn_hidden[-1],
                                                                    lstm_hidden[-1]))
        self.fusion = nn.Linear(4 * classes, classes)

    def features(self, x: Tensor) -> list[Tensor]:
        """The last hidden vector of each branch: MLP (B, 16), CNN (B, 512), RNN (B, 64), LSTM (B, 32)."""
        x = self.prepare(x)
        b1, b2, b3, b4 = (branch(x) for branch in self.branches)
        h1 = self.mlp(b1.flatten(1))
        c = F.relu(self.conv(_fuse(b2, self._context(0, h1)).transpose(1, 2)))
        c = self.dropout(self.pool(c))  # (B, 32, 15)
        h2 = F.relu(self.cnn_fc(c.flatten(1)))  # 480 -> 512
        r = self.rnns[0](b3, self._context(1, h2))
        for rnn in self.rnns[1:]:
            r, _ = rnn(r)
        h3 = r[:, -1]
        s = _fuse(b4, self._context(2, h3))
        for lstm in self.lstms:
            s, _ = lstm(s)
        h4 = s[:, -1]
        return [h1, h2, h3, h4]

    def _context(self, branch: int, hidden: Tensor) -> Tensor:
        """What the next branch is fused with: the hidden vector, or this branch's class probabilities."""
        return hidden if self.fuse == "hidden" else self.heads[branch](hidden).softmax(dim=1)

    def branch_logits(self, x: Tensor) -> list[Tensor]:
        """The four branch heads' logits (for the optional auxiliary losses)."""
        return [head(h) for head, h in zip(self.heads, self.features(x), strict=True)]

    def forward(self, x: Tensor) -> Tensor:
        return self.fusion(torch.cat(self.branch_logits(x), dim=1))
