"""List the models of ``params.yaml`` with their parameter counts.  Run: python -m toolpath.models"""

from __future__ import annotations

import sys

from rich.console import Console
from rich.table import Table

from toolpath.models.registry import build, parameter_count
from toolpath.pipeline import config


def main(argv: list[str] | None = None) -> int:
    models = config.load().models
    table = Table(title="models (conf/model, composed into params.yaml)")
    for column in ("name", "class", "parameters"):
        table.add_column(column, justify="right" if column == "parameters" else "left")
    for name in models:
        model = build(models[name])
        table.add_row(name, type(model).__name__, f"{parameter_count(model):,}")
    Console().print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
