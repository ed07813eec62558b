"""Every value of the composed configuration is checked before a stage uses it: one line naming the
key, the value and what is allowed, instead of a traceback deep in a stage or a silently wrong run.

Two layers.  *Types and keys* come from ``conf/`` composed with no override (the default profile is
the reference): a key the reference does not have is unknown (the line lists the keys that are
there), and a value must have its reference's type (an integer where a float is expected is fine;
a reference of ``null`` accepts anything).  *Ranges* are the rules below, by dotted key pattern
(``*`` is one key), plus the checks that tie keys together (Table 1 bounds increasing, the split
fractions summing to one, QAT freezing after its observers saw data, every shape configured).

:func:`check` runs where a configuration is composed (``python -m toolpath.pipeline.config``, the sweep)
and, through :func:`toolpath.pipeline.config.load`, in the first stage that reads a new ``params.yaml`` (so
``dvc exp run -S ...`` stops before any work); a checked file is remembered by its hash.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from typing import Any

# keys under these may be added freely (names of models, per-model overrides, roughness overrides)
FREE = ("models", "models.*", "train.per_model", "train.per_model.*", "train.protocol.lr", "train.protocol.structure",
        "train.protocol.structure.*", "train.protocol.tune.structure", "train.protocol.tune.structure.*",
        "qat.float_modules",
        "qat.per_model",
        "generate.*.roughness", "sweep", "hydra")


class ConfigError(SystemExit):
    """A bad configuration value: exits with its one-line message (code 1)."""


def _int(lo: int | None = None, hi: int | None = None) -> Callable[[Any], str | None]:
    def rule(v: Any) -> str | None:
        if isinstance(v, bool) or not isinstance(v, int):
            return "must be a whole number" + (f" >= {lo}" if lo is not None else "")
        if lo is not None and v < lo or hi is not None and v > hi:
            return f"must be a whole number in {lo}..{hi}" if hi is not None else f"must be a whole number >= {lo}"
        return None
    return rule


def _real(gt: float | None = None, ge: float | None = None, lt: float | None = None, le: float | None = None,
          nullable: bool = False) -> Callable[[Any], str | None]:
    bounds = " and ".join(f"{op} {b:g}" for op, b in ((">", gt), (">=", ge), ("<", lt), ("<=", le)) if b is not None)
    what = f"must be a number {bounds}".rstrip() + (" (or null)" if nullable else "")

    def rule(v: Any) -> str | None:
        if v is None:
            return None if nullable else what
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            return what
        if (gt is not None and not v > gt) or (ge is not None and not v >= ge) or (lt is not None and not v < lt) or \
                (le is not None and not v <= le):
            return what
        return None
    return rule


POSITIVE, FRACTION = _real(gt=0), _real(gt=0, lt=1)
RULES: dict[str, Callable[[Any], str | None]] = {
    "seed": _int(0), "window": _int(10), "stride": _int(1), "workers": _int(1),
    "label.window": _int(10), "label.stride": _int(1), "label.split.*": FRACTION,
    "gcode.read.chord_tolerance": POSITIVE,
    "gcode.write.decimals": _int(0, 9), "gcode.write.feed": POSITIVE, "gcode.write.plunge_feed": POSITIVE,
    "train.replicates": _int(1), "train.per_shape.*.epochs": _int(1), "train.per_model.*.epochs": _int(1),
    "train.protocol.settings.epochs": _int(1), "train.protocol.lr.*": _real(gt=0, nullable=True),
    "models.*.schedule.epochs": _int(1), "models.*.schedule.per_shape.*.epochs": _int(1),
    "models.*.schedule.lr": POSITIVE, "models.*.schedule.per_shape.*.lr": POSITIVE,
    "generate.*.programs": _int(4),
    "train.per_shape.*.batch_size": _int(1), "train.per_shape.*.lr": _real(gt=0, nullable=True),
    "train.common.lr": _real(gt=0, nullable=True), "train.per_model.*.lr": _real(gt=0),
    "train.per_shape.*.decay_rate": _real(gt=0, le=1), "train.per_shape.*.decay_steps": _int(1),
    "resources.workers.*": _int(1),
    "train.common.threads": _int(1), "train.common.warmup": _real(ge=0, lt=1), "train.common.weight_decay": _real(ge=0),
    "train.common.clip_grad_norm": _real(gt=0, nullable=True), "train.common.aux_loss_weight": _real(ge=0),
    "train.common.patience": _int(1),
    "generalise.schedule.epochs": _int(1), "generalise.schedule.batch_size": _int(1),
    "generalise.schedule.lr": POSITIVE, "generalise.threads": _int(1),
    "optimize.tolerance": POSITIVE, "optimize.penalty_weight": _real(ge=0), "optimize.box": POSITIVE,
    "optimize.sample.per_category.*": _int(1),
    "optimize.sample.per_category_by_mode.*": _int(1),
    "optimize.sample.baselines_per_category": _int(0), "optimize.mean_filter.width": _int(1),
    "optimize.mean_filter.passes": _int(1), "optimize.bezier.degree": _int(1, 30),
    "optimize.nacoa.population": _int(2), "optimize.nacoa.generations": _int(1),
    "optimize.nacoa.hba_generations": _int(0),
    "qat.epochs": _int(2), "qat.freeze_last": _int(1), "qat.lr_scale": POSITIVE,
    "qat.train_windows": _int(1), "qat.per_model.*.epochs": _int(2),
    "benchmark.threads": _int(1), "benchmark.repeats": _int(1), "benchmark.warmup": _int(0), "benchmark.batch": _int(1),
    "benchmark.large_batch": _int(1), "benchmark.split_repeats": _int(1), "benchmark.max_drop_points": _real(ge=0),
    "feedrate.machine.*": POSITIVE, "feedrate.blend_tolerance": POSITIVE,
    "feedrate.band": _real(ge=0, nullable=True),  # 0: point by point; null: the paper's interval rule
    "feedrate.bounds_every": _int(1),
    "sheets.width": POSITIVE, "sheets.height": POSITIVE,
}


def _leaves(node: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    if isinstance(node, Mapping):
        for key, value in node.items():
            yield from _leaves(value, f"{path}.{key}" if path else str(key))
    else:
        yield path, node


def _matches(path: str, pattern: str) -> bool:
    """``pattern`` with ``*`` standing for exactly one key."""
    parts, wanted = path.split("."), pattern.split(".")
    return len(parts) == len(wanted) and all(w == "*" or w == p for p, w in zip(parts, wanted, strict=True))


def _free(path: str) -> bool:
    parts = path.split(".")
    return any(_matches(".".join(parts[:k]), pattern) for k in range(1, len(parts)) for pattern in FREE)


def _node(tree: Any, path: str) -> Any:
    for key in path.split(".") if path else []:
        if not isinstance(tree, Mapping):
            return KeyError
        if key in tree:
            tree = tree[key]
        elif key.lstrip("-").isdigit() and int(key) in tree:  # YAML integer keys (optimize.dispatch)
            tree = tree[int(key)]
        else:
            return KeyError
    return tree


def _type_problem(value: Any, reference: Any) -> str | None:
    if reference is None:
        return None
    if isinstance(reference, bool):
        return None if isinstance(value, bool) else "must be true or false"
    if isinstance(reference, int):
        return None if isinstance(value, int) and not isinstance(value, bool) else "must be a whole number"
    if isinstance(reference, float):
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        return None if ok else "must be a finite number"
    if isinstance(reference, str):
        return None if isinstance(value, str) else "must be text"
    if isinstance(reference, list):
        return None if isinstance(value, list) else "must be a list"
    return None


def problems(cfg: Mapping, reference: Mapping) -> Iterator[str]:
    """Every problem of ``cfg`` (plain containers) against the ``reference`` composition, one line each."""
    for path, value in _leaves(cfg):
        rule = next((rule for pattern, rule in RULES.items() if _matches(path, pattern)), None)
        if _free(path):  # names are free here; a value with a rule is still checked
            if rule is not None and (why := rule(value)) is not None:
                yield f"{path} = {value!r}: {why}"
            continue
        ref = _node(reference, path)
        if ref is KeyError:
            parent = path.rpartition(".")[0]
            siblings = _node(reference, parent)
            if isinstance(siblings, Mapping):
                yield f"{path}: unknown key; {parent or 'the top level'} has {', '.join(map(str, siblings))}"
            else:
                yield f"{path}: unknown key"
            continue
        if isinstance(ref, Mapping) and not isinstance(value, Mapping):
            if value is not None:  # null: an empty section
                yield f"{path} = {value!r}: must be a section with {', '.join(map(str, ref))}"
            continue
        if path.endswith("._target_") or value is None and ref is None:
            continue
        why = rule(value) if rule is not None else _type_problem(value, ref)
        if why is not None:
            yield f"{path} = {value!r}: {why}"
    yield from _relations(cfg)


def _section(cfg: Mapping, key: str) -> Mapping:
    """A section, or {} when it is missing or not a mapping (the key-by-key check reports that)."""
    value = cfg.get(key)
    return value if isinstance(value, Mapping) else {}


def _relations(cfg: Mapping) -> Iterator[str]:
    label = _section(cfg, "label")
    bounds = label.get("bounds")
    if isinstance(bounds, list) and (len(bounds) != 3 or not all(isinstance(b, int | float) for b in bounds)
                                     or not 0 < bounds[0] < bounds[1] < bounds[2]):
        yield f"label.bounds = {bounds!r}: must be three increasing positive numbers (Table 1)"
    split = label.get("split")
    if isinstance(split, Mapping) and all(isinstance(v, int | float) for v in split.values()) and \
            abs(sum(split.values()) - 1.0) > 1e-9:
        yield f"label.split = {dict(split)!r}: the fractions must sum to 1"
    qat = _section(cfg, "qat")
    if isinstance(qat.get("epochs"), int) and isinstance(qat.get("freeze_last"), int) and \
            not qat["freeze_last"] < qat["epochs"]:
        yield (f"qat.freeze_last = {qat['freeze_last']}: must be below qat.epochs ({qat['epochs']}): the observers "
               "must see data before they freeze")
    shapes = cfg.get("shapes")
    for shape in shapes if isinstance(shapes, list) else []:
        for section, where in (("generate", _section(cfg, "generate")),
                               ("train.per_shape", _section(_section(cfg, "train"), "per_shape"))):
            if shape not in where:
                generate = _section(cfg, "generate")
                known = [k for k, v in generate.items() if isinstance(v, Mapping) and "programs" in v]
                yield (f"shapes: {shape!r} has no {section}.{shape} section; the configured shapes are "
                       f"{', '.join(known)}")
                break
    protocol = _section(_section(cfg, "train"), "protocol")
    for name in protocol.get("models") or []:
        if name not in _section(cfg, "models") or _section(protocol, "lr").get(name) is None:
            yield (f"train.protocol.models: {name!r} needs a models.{name} section and a learning rate in "
                   f"train.protocol.lr")
    yield from _unused_common_rate(cfg, protocol)
    window = label.get("window")
    for name, model in _section(cfg, "models").items():
        if isinstance(model, Mapping) and "window" in model and model["window"] != window:
            yield f"models.{name}.window = {model['window']!r}: must equal label.window ({window})"
        schedule = model.get("schedule") if isinstance(model, Mapping) else None
        per_shape = schedule.get("per_shape") if isinstance(schedule, Mapping) else None
        for shape in per_shape if isinstance(per_shape, Mapping) else []:
            if shape not in _section(_section(cfg, "train"), "per_shape"):
                yield (f"models.{name}.schedule.per_shape.{shape}: no such shape; the configured shapes are "
                       f"{', '.join(str(s) for s in shapes or [])}")


def _unused_common_rate(cfg: Mapping, protocol: Mapping) -> Iterator[str]:
    """A ``train.common.lr`` that no trained model would use (the protocol's rates win for the models it
    lists; the exact rule has none): a sweep of it would change nothing."""
    train = _section(cfg, "train")
    rate = _section(train, "common").get("lr")
    trained = train.get("models") if isinstance(train.get("models"), list) else []
    listed = protocol.get("models") or []
    outside = [m for m in trained if m not in listed and
               not str(_section(_section(cfg, "models"), m).get("_target_", "")).endswith("LocalCurvatureRule")]
    if rate is not None and trained and not outside:
        yield (f"train.common.lr = {rate!r}: no trained model uses it, since train.protocol.models lists every "
               "learned model of train.models; set train.protocol.lr.<model> (or train.protocol.models=[] "
               "to train each model on its own schedule)")


def check(cfg: Mapping, reference: Mapping, source: str = "params.yaml") -> None:
    """Raise :class:`ConfigError` with the first problem (and how many more there are)."""
    found = list(problems(cfg, reference))
    if found:
        more = f" (and {len(found) - 1} more)" if len(found) > 1 else ""
        raise ConfigError(f"{source}: {found[0]}{more}")
