"""The training loop behind every learned model: Adam, a learning-rate schedule, cross-entropy.

Eq. 29 (categorical cross-entropy) is ``F.cross_entropy`` on logits.  Two schedules:

* ``step`` (Table 2): ``lr * decay_rate ** floor(step / decay_steps)`` per optimiser step (the
  paper's "decay rate" and "decay steps"); with few epochs the staircase never fires.
* ``onecycle``: warm-up over the first ``warmup`` share of the steps actually run, then cosine
  annealing to ~0 (torch's ``OneCycleLR``): a schedule scaled to the run, whatever its length.

Gradients are clipped to ``clip_grad_norm`` (global 2-norm) when set.  With ``restore_best`` the
weights of the epoch with the lowest validation loss are restored at the end; ``patience`` stops
early.  Every random choice (initialisation, shuffling, dropout, augmentation) draws from ``seed``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from toolpath.models.inputs import Prepare, random_reversal, random_rotation_reflection


@dataclass(frozen=True)
class TrainSettings:
    """Optimiser and schedule; every field is a key of ``conf/train``."""

    lr: float = 1e-3
    decay_rate: float = 0.9
    decay_steps: int = 500
    batch_size: int = 64
    epochs: int = 20
    patience: int | None = None  # epochs without a better validation loss before stopping
    weight_decay: float = 0.0
    augment: bool = False  # random rotation / reflection / reversal of training windows
    aux_loss_weight: float = 0.0  # MCRL only: weight of the per-branch auxiliary losses
    schedule: str = "step"  # "step" (Table 2's staircase) or "onecycle" (warm-up, cosine decay)
    warmup: float = 0.3  # onecycle: share of the steps spent warming up
    clip_grad_norm: float | None = None  # clip the global gradient norm to this (None: no clipping)
    restore_best: bool = False  # end with the weights of the best-validation-loss epoch
    normalise_inputs: bool = False  # scale each input feature to unit RMS over the training windows
    seed: int = 0


@dataclass(frozen=True)
class EpochRecord:
    """Per-epoch figures (the data behind Figs. 6-7)."""

    epoch: int
    lr: float
    train_loss: float
    train_accuracy: float
    val_loss: float
    val_accuracy: float


def predict_logits(net: nn.Module, X: torch.Tensor, batch_size: int = 1024) -> torch.Tensor:
    """Logits of ``net`` in eval mode, in batches, without gradients."""
    net.eval()
    with torch.no_grad():
        return torch.cat([net(X[i : i + batch_size]) for i in range(0, len(X), batch_size)]) if len(X) else \
            torch.zeros((0, 4))


def _loss(net: nn.Module, xb: torch.Tensor, yb: torch.Tensor, weight: torch.Tensor | None,
          aux_weight: float) -> tuple[torch.Tensor, torch.Tensor]:
    if aux_weight > 0 and hasattr(net, "branch_logits"):
        branches = net.branch_logits(xb)
        logits = net.fusion(torch.cat(branches, dim=1))
        aux = sum(F.cross_entropy(b, yb, weight=weight) for b in branches) / len(branches)
        return F.cross_entropy(logits, yb, weight=weight) + aux_weight * aux, logits
    logits = net(xb)
    return F.cross_entropy(logits, yb, weight=weight), logits


def _evaluate(net: nn.Module, X: torch.Tensor, y: torch.Tensor, weight: torch.Tensor | None) -> tuple[float, float]:
    if len(X) == 0:
        return float("nan"), float("nan")
    logits = predict_logits(net, X)
    return float(F.cross_entropy(logits, y, weight=weight)), float((logits.argmax(1) == y).float().mean())


SCHEDULES = ("step", "onecycle")


def _scheduler(optimiser: torch.optim.Optimizer, settings: TrainSettings, steps: int):
    """The per-step learning-rate schedule ``settings.schedule`` names (module docstring)."""
    if settings.schedule == "step":
        return torch.optim.lr_scheduler.StepLR(optimiser, step_size=settings.decay_steps, gamma=settings.decay_rate)
    if settings.schedule == "onecycle":
        return torch.optim.lr_scheduler.OneCycleLR(optimiser, max_lr=settings.lr, total_steps=max(steps, 1),
                                                   pct_start=settings.warmup, anneal_strategy="cos",
                                                   cycle_momentum=False)
    raise ValueError(f"train schedule must be one of {SCHEDULES}, got {settings.schedule!r}")


def fit_network(net: nn.Module, X: np.ndarray, y: np.ndarray, settings: TrainSettings,
                X_val: np.ndarray | None = None, y_val: np.ndarray | None = None,
                class_weight: np.ndarray | None = None,
                on_epoch: Callable[[EpochRecord], None] | None = None) -> list[EpochRecord]:
    """Train ``net`` in place on class indices ``y`` (0-based); returns the per-epoch history."""
    generator = torch.Generator().manual_seed(settings.seed)
    Xt, yt = torch.as_tensor(X, dtype=torch.float32), torch.as_tensor(y, dtype=torch.long)
    has_val = X_val is not None and len(X_val) > 0
    Xv = torch.as_tensor(X_val if has_val else np.zeros((0, *X.shape[1:])), dtype=torch.float32)
    yv = torch.as_tensor(y_val if has_val else np.zeros(0), dtype=torch.long)
    weight = None if class_weight is None else torch.as_tensor(class_weight, dtype=torch.float32)
    if settings.normalise_inputs and isinstance(getattr(net, "prepare", None), Prepare):
        net.prepare.fit_scale(Xt)
    # fused: one kernel for all parameters; the per-parameter loop was a tenth of a small model's step
    optimiser = torch.optim.Adam(net.parameters(), lr=settings.lr, weight_decay=settings.weight_decay, fused=True)
    schedule = _scheduler(optimiser, settings, steps=settings.epochs * -(-len(Xt) // settings.batch_size))
    history: list[EpochRecord] = []
    best_loss, best_state, stale = float("inf"), None, 0
    for epoch in range(1, settings.epochs + 1):
        net.train()
        order = torch.randperm(len(Xt), generator=generator)
        lr = optimiser.param_groups[0]["lr"]
        total, correct, seen = 0.0, 0, 0
        for start in range(0, len(order), settings.batch_size):
            idx = order[start : start + settings.batch_size]
            xb, yb = Xt[idx], yt[idx]
            if settings.augment:
                xb = random_reversal(random_rotation_reflection(xb, generator), generator)
            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(int(torch.randint(0, 2**31 - 1, (1,), generator=generator)))  # dropout
                loss, logits = _loss(net, xb, yb, weight, settings.aux_loss_weight)
                optimiser.zero_grad(set_to_none=True)
                loss.backward()
            if settings.clip_grad_norm is not None:
                nn.utils.clip_grad_norm_(net.parameters(), settings.clip_grad_norm)
            optimiser.step()
            schedule.step()  # per optimiser step, as Table 2's decay steps count
            total += float(loss.detach()) * len(idx)
            correct += int((logits.argmax(1) == yb).sum())
            seen += len(idx)
        val_loss, val_acc = _evaluate(net, Xv, yv, weight)
        record = EpochRecord(epoch, lr, total / max(seen, 1), correct / max(seen, 1), val_loss, val_acc)
        history.append(record)
        if on_epoch is not None:
            on_epoch(record)
        if has_val and (settings.patience is not None or settings.restore_best):
            if val_loss < best_loss - 1e-6:
                best_loss, best_state, stale = val_loss, copy.deepcopy(net.state_dict()), 0
            else:
                stale += 1
                if settings.patience is not None and stale >= settings.patience:
                    break
    if best_state is not None:
        net.load_state_dict(best_state)
    net.eval()
    return history
