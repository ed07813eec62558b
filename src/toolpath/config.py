"""``conf/`` (Hydra) is the one source of truth; ``params.yaml`` is its composition.

Run: ``python -m toolpath.config [OVERRIDE ...]`` (e.g. ``+experiment=smoke``) rewrites
``params.yaml`` with DVC's own compose function, so the bytes equal what ``dvc exp run`` writes.
Stages call :func:`load` and read only the sections they declare in ``dvc.yaml``.
"""

from __future__ import annotations

import sys
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

PARAMS_FILE = "params.yaml"
CONF_DIR = "conf"


def compose(overrides: Sequence[str] = (), root: Path | None = None, output: Path | None = None) -> Path:
    """Compose ``root/conf`` with ``overrides`` into ``output`` (default ``root/params.yaml``)."""
    from dvc.utils.hydra import compose_and_dump  # DVC's code: byte-identical to `dvc exp run`

    root = Path(root or Path.cwd()).resolve()
    output = Path(output or root / PARAMS_FILE)
    compose_and_dump(output, str(root / CONF_DIR), None, "config", str(root), list(overrides))
    return output


def load(path: str | Path = PARAMS_FILE) -> DictConfig:
    """The composed parameters; a clear error when ``params.yaml`` is missing."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: run `python -m toolpath.config` (or `make repro`) first")
    return OmegaConf.load(path)


def seed_for(seed: int, *keys: str) -> int:
    """A 32-bit seed derived from the global ``seed`` and stable names (stage, shape ...)."""
    import numpy as np

    entropy = [int(seed)] + [zlib.crc32(k.encode()) for k in keys]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])


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
