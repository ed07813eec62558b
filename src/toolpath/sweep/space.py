"""The search space of ``conf/sweep/<name>.yaml``: Optuna distributions and Hydra overrides.

Each entry names the config key it overrides (``train.per_shape.{shape}.lr``, ``models.mcrl.dropout``) and a
distribution: ``float`` (``low``, ``high``, ``log``), ``int`` (``low``, ``high``, ``step``) or
``choice`` (``choices``).  Optuna's categorical values must be scalars, so a list choice (hidden
sizes) is offered as its text (``"128,64,32,16"``) and turned back into the list for the override.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import optuna

KINDS = ("float", "int", "choice")


def _as_text(value: Any) -> Any:
    return ",".join(str(v) for v in value) if isinstance(value, list | tuple) else value


@dataclass(frozen=True)
class Param:
    """One dimension of the search: the config ``key`` it sets and its distribution."""

    name: str
    key: str
    kind: str
    low: float | None = None
    high: float | None = None
    log: bool = False
    step: int | None = None
    choices: tuple = ()

    def suggest(self, trial: optuna.Trial) -> Any:
        """Sample this dimension in ``trial`` (Optuna's value: a list choice as its text)."""
        if self.kind == "float":
            return trial.suggest_float(self.name, self.low, self.high, log=self.log)
        if self.kind == "int":
            return trial.suggest_int(self.name, int(self.low), int(self.high), step=int(self.step or 1), log=self.log)
        return trial.suggest_categorical(self.name, [_as_text(c) for c in self.choices])

    def value(self, sampled: Any) -> Any:
        """The config value of a sampled Optuna value (a list choice back from its text)."""
        if self.kind != "choice":
            return sampled
        return next(c for c in self.choices if _as_text(c) == sampled)

    def sampled(self, value: Any) -> Any | None:
        """The Optuna value of a config value, or None when the value lies outside the space."""
        if self.kind == "choice":
            text = _as_text(list(value) if isinstance(value, list | tuple) else value)
            return text if text in [_as_text(c) for c in self.choices] else None
        return value if self.low <= value <= self.high else None


def parse_space(space: Mapping[str, Mapping[str, Any]], shape: str) -> list[Param]:
    """The ``space`` section of a sweep config; a ValueError names the entry that is malformed."""
    params = []
    for name, entry in space.items():
        kind = entry.get("type")
        if kind not in KINDS:
            raise ValueError(f"sweep.space.{name}: type must be one of {', '.join(KINDS)}, not {kind!r}")
        if "key" not in entry:
            raise ValueError(f"sweep.space.{name}: missing 'key' (the config key it overrides)")
        if kind == "choice" and not entry.get("choices"):
            raise ValueError(f"sweep.space.{name}: a choice needs a non-empty 'choices' list")
        if kind != "choice" and not (entry.get("low") is not None and entry.get("high") is not None
                                     and entry["low"] < entry["high"]):
            raise ValueError(f"sweep.space.{name}: needs low < high")
        choices = tuple(list(c) if isinstance(c, list | tuple) else c for c in entry.get("choices") or ())
        params.append(Param(name=name, key=str(entry["key"]).format(shape=shape), kind=kind,
                            low=entry.get("low"), high=entry.get("high"), log=bool(entry.get("log", False)),
                            step=entry.get("step"), choices=choices))
    return params


def suggest(trial: optuna.Trial, params: list[Param]) -> dict[str, Any]:
    """Config values (by param name) sampled for ``trial``."""
    return {p.name: p.value(p.suggest(trial)) for p in params}


def overrides(params: list[Param], values: Mapping[str, Any]) -> list[str]:
    """Hydra overrides setting each param's key to its value (lists in Hydra's list syntax)."""
    out = []
    for p in params:
        value = values[p.name]
        text = "[" + ",".join(str(v) for v in value) + "]" if isinstance(value, list | tuple) else repr(value) \
            if isinstance(value, float) else str(value)
        out.append(f"{p.key}={text}")
    return out
