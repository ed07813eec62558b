"""``conf/`` (Hydra) is the one source of truth; ``params.yaml`` is its composition.

Run: ``python -m toolpath.pipeline.config [OVERRIDE ...]`` (e.g. ``+experiment=smoke``) rewrites
``params.yaml`` with DVC's own compose function, so the bytes equal what ``dvc exp run`` writes.
Stages call :func:`load` and read only the sections they declare in ``dvc.yaml``.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from toolpath.pipeline.seeds import seed_for

__all__ = ["compose", "compose_config", "flat", "load", "seed_for"]

PARAMS_FILE = "params.yaml"
CONF_DIR = "conf"


def compose(overrides: Sequence[str] = (), root: Path | None = None, output: Path | None = None) -> Path:
    """Compose ``root/conf`` with ``overrides`` into ``output`` (default ``root/params.yaml``)."""
    from dvc.utils.hydra import compose_and_dump  # DVC's code: byte-identical to `dvc exp run`

    root = Path(root or Path.cwd()).resolve()
    output = Path(output or root / PARAMS_FILE)
    compose_and_dump(output, str(root / CONF_DIR), None, "config", str(root), list(overrides))
    return output


def compose_config(root: Path, overrides: Sequence[str] = ()) -> DictConfig:
    """``root/conf`` composed with ``overrides`` and resolved, in memory (what :func:`compose` writes to
    ``params.yaml``; the sweep composes each trial's config with it).

    Hydra composes in two steps: the config groups chosen (the defaults list, then every file merged: most
    of a second here) and then the value overrides, set on the merged config in order.  The first step's
    result is kept per content of ``conf/`` and choice of groups, so a sweep's trials or a run of checks
    that differ in values only pay the second; the value overrides go through Hydra's own function, with
    its errors.  A Hydra without that function composes every call whole (the same result, slower)."""
    import copy

    from hydra.core.override_parser.overrides_parser import OverridesParser

    conf = Path(root).resolve() / CONF_DIR
    try:
        from hydra._internal.config_loader_impl import ConfigLoaderImpl

        apply_values = ConfigLoaderImpl._apply_overrides_to_config
    except (ImportError, AttributeError):  # another Hydra's internals
        cfg = _hydra_compose(conf, overrides)
        OmegaConf.resolve(cfg)
        return cfg
    parsed = OverridesParser.create().parse_overrides(list(overrides))
    if any(o.is_sweep_override() or _names_hydra(o.key_or_group) for o in parsed):
        groups, values = list(overrides), []  # Hydra's own refusal or setting, as it composes them
    else:  # Hydra's rule: a group override names a group (a folder of conf/) and sets no dict
        grouped = [(conf / o.key_or_group).is_dir() and not isinstance(o.value(), dict) for o in parsed]
        groups = [o.input_line for o, group in zip(parsed, grouped, strict=True) if group]
        values = [o for o, group in zip(parsed, grouped, strict=True) if not group]
    key = (_conf_digest(conf).hexdigest(), tuple(groups))
    if key not in _MERGED:
        if len(_MERGED) >= 8:  # a few choices of groups kept (a sweep's, a check run's), the oldest dropped
            del _MERGED[next(iter(_MERGED))]
        _MERGED[key] = _hydra_compose(conf, groups)
    cfg = copy.deepcopy(_MERGED[key])
    apply_values(values, cfg)
    OmegaConf.resolve(cfg)
    return cfg


_MERGED: dict[tuple, DictConfig] = {}


def _names_hydra(key: str) -> bool:
    """Whether an override's key is Hydra's own node or groups (``hydra.*``, ``hydra/*``)."""
    return key.replace("/", ".").split(".")[0] == "hydra"


def _hydra_compose(conf: Path, overrides: Sequence[str]) -> DictConfig:
    """Hydra's composition of ``conf`` with ``overrides``, unresolved."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(conf), version_base=None):
        return hydra_compose(config_name="config", overrides=list(overrides))


def load(path: str | Path = PARAMS_FILE) -> DictConfig:
    """The composed parameters, checked against ``conf/`` (:mod:`toolpath.pipeline.schema`) the first time a
    given ``params.yaml`` is read; one clear line when it is missing, unreadable or holds a bad value."""
    from toolpath.pipeline.schema import ConfigError

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: run `python -m toolpath.pipeline.config` (or `make repro`) first")
    try:
        cfg = OmegaConf.load(path)
    except Exception as exc:  # noqa: BLE001 - YAML and OmegaConf errors alike: one line naming the file
        raise ConfigError(f"{path}: not a readable configuration ({_one_line(exc)})") from None
    _check_once(path, cfg)
    return cfg


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:400]


def reference(root: Path) -> dict:
    """``root/conf`` composed with no override: the keys and types every configuration must keep.
    Kept per content of ``conf/`` (a second check in one process, as a sweep's trials or a test's, costs no
    second composition); a copy, so a caller cannot change the kept one."""
    import copy

    key = _conf_digest(Path(root) / CONF_DIR).hexdigest()
    if key not in _REFERENCES:
        _REFERENCES[key] = OmegaConf.to_container(compose_config(root), resolve=True)
    return copy.deepcopy(_REFERENCES[key])


_REFERENCES: dict[str, dict] = {}


def _conf_digest(conf: Path, start: bytes = b""):
    """sha256 over ``start`` and every YAML file of ``conf`` (name and bytes), in a fixed order."""
    import hashlib

    digest = hashlib.sha256(start)
    for file in sorted(conf.rglob("*.yaml")):
        digest.update(file.relative_to(conf).as_posix().encode() + b"\0" + file.read_bytes())
    return digest


def validate(cfg: DictConfig | Mapping, root: Path, source: str = PARAMS_FILE) -> None:
    """Check a composed configuration against ``root/conf`` (raises :class:`toolpath.pipeline.schema.ConfigError`)."""
    from toolpath.pipeline.schema import check

    plain = OmegaConf.to_container(cfg, resolve=True) if isinstance(cfg, DictConfig) else cfg
    check(plain, reference(root), source)


def _check_once(path: Path, cfg: DictConfig) -> None:
    """Validate ``params.yaml`` unless this exact file (with this ``conf/``) was checked before: the
    first stage of a run pays for the composition, the others read a stamp in ``.dvc/tmp``."""
    root = path.resolve().parent
    conf, stamp_dir = root / CONF_DIR, root / ".dvc" / "tmp"
    if not conf.is_dir():  # a params.yaml outside a checkout (tests' scratch folders): nothing to compare with
        return
    digest = _conf_digest(conf, path.read_bytes())
    stamp = stamp_dir / "params-checked"
    if stamp.is_file() and stamp.read_text() == digest.hexdigest():
        return
    validate(cfg, root, str(path))
    if stamp_dir.is_dir():
        stamp.write_text(digest.hexdigest())


def flat(node: Any, prefix: str = "") -> dict[str, Any]:
    """Dotted keys of a nested config, for MLflow params (lists joined as text)."""
    if isinstance(node, DictConfig | ListConfig):
        node = OmegaConf.to_container(node, resolve=True)
    out: dict[str, Any] = {}
    if isinstance(node, Mapping):
        for key, value in node.items():
            out.update(flat(value, f"{prefix}.{key}" if prefix else str(key)))
    else:
        out[prefix] = node
    return out


def main(argv: list[str] | None = None) -> int:
    """Compose, check, then write ``params.yaml``; a bad override or value is one line and exit code 1,
    and ``params.yaml`` is left as it was."""
    from toolpath.pipeline.schema import ConfigError

    overrides = sys.argv[1:] if argv is None else argv
    root = Path.cwd()
    try:
        cfg = compose_config(root, overrides)
    except Exception as exc:  # noqa: BLE001 - Hydra's override / missing-config errors: one line, not 59
        print(f"toolpath.pipeline.config: {_one_line(exc)}", file=sys.stderr)
        return 1
    try:
        validate(cfg, root, "the composed configuration")
    except ConfigError as exc:
        print(f"toolpath.pipeline.config: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {compose(overrides)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
