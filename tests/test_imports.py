"""Imports flow one way: every sub-package imports on its own in a fresh interpreter, and no domain
package pulls in Hydra, DVC or MLflow (only stages, the sweep, config and tracking may)."""

import subprocess
import sys

import pytest

DOMAIN = ("gcode", "geometry", "geometry.labels", "shapes", "shapes.sequencing", "models", "models.training",
          "smoothing", "corners", "inference", "feedrate", "smooth", "reports")
WIRING = ("stages", "sweep", "pipeline.config", "pipeline.tracking", "cli", "pipeline.stage_times")
CHECK = """
import importlib, sys
importlib.import_module("toolpath.{name}")
print(",".join(sorted(m for m in ("hydra", "dvc", "mlflow") if m in sys.modules)))
"""


@pytest.mark.parametrize("name", DOMAIN + WIRING)
def test_each_sub_package_imports_on_its_own(name):
    done = subprocess.run([sys.executable, "-c", CHECK.format(name=name)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    if name in DOMAIN:
        assert done.stdout.strip() == "", f"toolpath.{name} imports {done.stdout.strip()}"


def test_every_module_imports():
    """Every module of the package imports (a name a package loads on first use hides a broken import from
    the sub-package test above)."""
    code = ("import importlib, pkgutil, toolpath\n"
            "names = [m.name for m in pkgutil.walk_packages(toolpath.__path__, 'toolpath.') "
            "if not m.name.endswith('__main__')]\n"
            "for name in names:\n    importlib.import_module(name)\nprint(len(names))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert int(done.stdout) > 100
