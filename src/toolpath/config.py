"""``conf/`` (Hydra) is the one source of truth; ``params.yaml`` is its composition.

Run: ``python -m toolpath.config [OVERRIDE ...]`` (e.g. ``+experiment=smoke``) rewrites
``params.yaml`` with DVC's own compose function, so the bytes equal what ``dvc exp run`` writes.
Stages call :func:`load` and read only the sections they declare in ``dvc.yaml``.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from toolpath.seeds import seed_for

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
    ``params.yaml``; the sweep composes each trial's config with it)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(Path(root).resolve() / CONF_DIR), version_base=None):
        cfg = hydra_compose(config_name="config", overrides=list(overrides))
    OmegaConf.resolve(cfg)
    return cfg


def load(path: str | Path = PARAMS_FILE) -> DictConfig:
    """The composed parameters; a clear error when ``params.yaml`` is missing."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: run `python -m toolpath.config` (or `make repro`) first")
    return OmegaConf.load(path)


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
    overrides = sys.argv[1:] if argv is None else argv
    print(f"wrote {compose(overrides)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
