"""MCRL's four branches as stand-alone baselines (Table 3 rows MLP, CNN, RNN, LSTM).

Each is the corresponding branch applied to the whole 50-point window, with the shared input
preparation but without the linear attention, resampling or fusion.
"""

from __future__ import annotations

import torch.nn.functional as F
from torch import Tensor, nn

from toolpath.models.inputs import Prepare


class MLP(nn.Module):
    """Flatten (100) -> 128 -> 64 -> 32 -> 16 (ReLU) -> 4."""

    def __init__(self, hidden: tuple[int, ...] = (128, 64, 32, 16), window: int = 50, classes: int = 4,
                 inputs: str = "turning") -> None:
        super().__init__()
        self.prepare = Prepare(inputs)
        dims = [window * 2, *hidden]
        layers = [m for a, b in zip(dims[:-1], dims[1:], strict=True) for m in (nn.Linear(a, b), nn.ReLU())]
        self.net = nn.Sequential(*layers, nn.Linear(dims[-1], classes))

    def forward(self, x: Tensor) -> Tensor:
        return self.net(self.prepare(x).flatten(1))


class CNN(nn.Module):
    """Conv1d 32 kernels of 3 -> ReLU -> MaxPool 2 -> Dropout -> flatten (25 x 32) -> 512 ReLU -> 4."""

    def __init__(self, channels: int = 32, hidden: int = 512, dropout: float = 0.2, window: int = 50,
                 classes: int = 4, inputs: str = "turning") -> None:
        super().__init__()
        self.prepare = Prepare(inputs)
        self.conv = nn.Conv1d(2, channels, kernel_size=3, padding=1)
        self.pool = nn.MaxPool1d(2)
        self.dropout = nn.Dropout(dropout)
        self.fc = nn.Linear(channels * (window // 2), hidden)
        self.head = nn.Linear(hidden, classes)

    def forward(self, x: Tensor) -> Tensor:
        c = F.relu(self.conv(self.prepare(x, channels_first=True)))  # functional ReLU: see MCRL docstring
        c = self.dropout(self.pool(c))
        return self.head(F.relu(self.fc(c.flatten(1))))


class _Recurrent(nn.Module):
    """Stacked single-layer recurrent modules of different widths; the last step feeds the head."""

    def __init__(self, cell: type[nn.RNN] | type[nn.LSTM], hidden: tuple[int, ...], classes: int,
                 inputs: str) -> None:
        super().__init__()
        self.prepare = Prepare(inputs)
        widths = [2, *hidden[:-1]]
        self.layers = nn.ModuleList(cell(a, b, batch_first=True) for a, b in zip(widths, hidden, strict=True))
        self.head = nn.Linear(hidden[-1], classes)

    def forward(self, x: Tensor) -> Tensor:
        h = self.prepare(x)
        for layer in self.layers:
            h, _ = layer(h)
        return self.head(h[:, -1])


class RNN(_Recurrent):
    """RNN 128 -> 64 -> 64 (tanh), last step -> 4."""

    def __init__(self, hidden: tuple[int, ...] = (128, 64, 64), window: int = 50, classes: int = 4,
                 inputs: str = "turning") -> None:
        super().__init__(nn.RNN, tuple(hidden), classes, inputs)


class LSTM(_Recurrent):
    """LSTM 64 -> 32 -> 32, last step -> 4."""

    def __init__(self, hidden: tuple[int, ...] = (64, 32, 32), window: int = 50, classes: int = 4,
                 inputs: str = "turning") -> None:
        super().__init__(nn.LSTM, tuple(hidden), classes, inputs)
