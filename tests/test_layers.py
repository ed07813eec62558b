"""The house's layers, read from the source itself (no import is executed):

* every DVC stage declares, as ``src/`` dependencies, its own module and every package its code can run:
  the closure of module-level imports from the stage module, plus the imports inside the pipeline
  functions it calls (``artifacts.load_classifier`` imports the networks, ``settings.training`` the loop);
* ``toolpath.smooth`` (the product) and ``toolpath.stages`` are leaves: nothing imports them, and no stage
  depends on the product, so a change confined to it leaves ``dvc status`` up to date;
* domain packages import neither the pipeline's wiring (configuration, settings, tracking, workers) nor
  Hydra, DVC or MLflow; they may use its pure parts, the seeds and the artifacts' schema and loaders, and
  its process pools;
* no import cycle between modules; no module over 400 lines; no stage module over 100.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"
PACKAGE = SRC / "toolpath"
DOMAIN = ("corners", "feedrate", "gcode", "geometry", "inference", "models", "reports", "shapes", "smoothing")
WIRING_LIBRARIES = ("hydra", "dvc", "mlflow")
# what domain packages may use of the pipeline: its pure parts, and process pools (forked by `make repro`'s warm
# server, else spawned: no configuration, tracking or wiring library)
PURE_PIPELINE = {"toolpath.pipeline", "toolpath.pipeline.seeds", "toolpath.pipeline.artifacts",
                 "toolpath.pipeline.warm", "toolpath.pipeline.warm_pool"}


def module_file(name: str) -> Path | None:
    path = SRC / name.replace(".", "/")
    if (path / "__init__.py").is_file():
        return path / "__init__.py"
    return path.with_suffix(".py") if path.with_suffix(".py").is_file() else None


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(nodes, importer: str, prefix: str = "toolpath") -> set[str]:
    """Modules named by the import statements among ``nodes`` (with every parent package: its
    ``__init__`` runs too)."""
    found = set()
    for node in nodes:
        if isinstance(node, ast.ImportFrom):
            name = node.module or ""
            if node.level:
                name = ".".join(importer.split(".")[:-node.level] + ([name] if name else []))
            if name.startswith(prefix):
                found.add(name)
                found |= {f"{name}.{a.name}" for a in node.names if module_file(f"{name}.{a.name}")}
                # a package that loads its names on first use (PEP 562) maps each to its module
                homes = lazy_names(name) if prefix == "toolpath" else {}
                found |= {f"{name}.{homes[a.name]}" for a in node.names if a.name in homes}
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith(prefix)}
    return {".".join(m.split(".")[:i]) for m in found for i in range(2, m.count(".") + 2)}


def lazy_names(package: str) -> dict[str, str]:
    """``{name: submodule}`` of a package that loads its names on first use (its ``_HOMES``), else {}."""
    path = module_file(package)
    if path is None or path.name != "__init__.py" or "_HOMES" not in path.read_text(encoding="utf-8"):
        return {}
    return dict(getattr(importlib.import_module(package), "_HOMES", {}))


def tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def closure(start: set[str]) -> set[str]:
    seen, todo = set(), set(start)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        if path := module_file(name):
            # an __init__ is its package's module; its body's imports count from the package
            todo |= imported(tree(path).body, name if path.name != "__init__.py" else f"{name}._") - seen
    return seen


def pipeline_calls(module: ast.Module) -> set[str]:
    """Imports inside the bodies of the pipeline functions a module calls (``artifacts.load_classifier``)."""
    aliases = {}
    for node in ast.walk(module):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("toolpath.pipeline"):
            aliases |= {a.asname or a.name: (node.module, a.name) for a in node.names}
    found = set()
    for node in ast.walk(module):
        target = None
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            target = (".".join(aliases[node.value.id]), node.attr)
        elif isinstance(node, ast.Name) and node.id in aliases and not module_file(".".join(aliases[node.id])):
            target = aliases[node.id]
        if target and (path := module_file(target[0])):
            for definition in tree(path).body:
                if isinstance(definition, ast.FunctionDef) and definition.name == target[1]:
                    found |= imported(ast.walk(definition), target[0])
    return found


def stage_packages(stage: str) -> set[str]:
    path = PACKAGE / "stages" / f"{stage}.py"
    module = tree(path)
    start = imported(ast.walk(module), module_name(path)) | pipeline_calls(module)
    return {name.split(".")[1] for name in closure(start)} - {"stages"}


STAGES = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_a_stage_depends_on_its_module_and_every_package_its_code_runs(stage):
    declared = {d for d in STAGES[stage]["deps"] if isinstance(d, str) and d.startswith("src/")}
    # the package's __init__ too: it pins the CPU kernels every stage runs (toolpath.CPU_PINS)
    files = {f"src/toolpath/stages/{stage}.py", "src/toolpath/__init__.py"}
    needed = files | {f"src/toolpath/{p}" for p in stage_packages(stage)}
    assert needed <= declared, f"dvc.yaml stage {stage} lacks {sorted(needed - declared)}"
    assert all((REPO / d).is_dir() or d in files for d in declared), \
        f"{stage}: a src/ dependency is a file, not a package (or does not exist): {sorted(declared)}"


def test_the_closure_sees_a_lazy_import_in_a_called_pipeline_function():
    # classify calls artifacts.load_classifier, whose body imports the networks: a real dependency
    assert "toolpath.models.training.classifier" in pipeline_calls(tree(PACKAGE / "stages" / "classify.py"))
    assert "models" in stage_packages("classify")


def test_the_closure_follows_a_name_a_package_loads_on_first_use():
    # `from toolpath.geometry.labels import label_program` runs labels.windows, which reads G-code
    statement = ast.parse("from toolpath.geometry.labels import label_program").body
    assert "toolpath.geometry.labels.windows" in imported(statement, "toolpath.stages.x")
    assert "gcode" in stage_packages("generate")


def test_no_stage_depends_on_the_product():
    for stage, spec in STAGES.items():
        assert not any("toolpath/smooth" in d and "smoothing" not in d for d in spec["deps"] if isinstance(d, str))
        assert "smooth" not in stage_packages(stage), stage


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in PACKAGE.rglob("*.py")}


def test_the_product_and_the_stages_are_leaves():
    for name, path in all_modules().items():
        importer = name if path.name != "__init__.py" else f"{name}._"
        targets = imported(ast.walk(tree(path)), importer)
        if not name.startswith("toolpath.smooth") and name != "toolpath.cli":
            assert not any(t == "toolpath.smooth" or t.startswith("toolpath.smooth.") for t in targets), name
        if not name.startswith("toolpath.stages"):
            assert not any(t.startswith("toolpath.stages") for t in targets), name


def test_domain_packages_stay_out_of_the_wiring():
    for name, path in all_modules().items():
        parts = name.split(".")
        if len(parts) < 2 or parts[1] not in DOMAIN or parts[-1] == "__main__":
            continue
        importer = name if path.name != "__init__.py" else f"{name}._"
        module = tree(path)
        wiring = {t for t in imported(ast.walk(module), importer) if t.startswith("toolpath.pipeline")}
        assert wiring <= PURE_PIPELINE, (name, wiring)
        for library in WIRING_LIBRARIES:
            assert not imported(ast.walk(module), importer, library), (name, library)


def test_no_import_cycle_between_modules():
    """Module-level imports (those that run when a module is imported) form no cycle."""
    modules = all_modules()
    edges = {}
    for name, path in modules.items():
        importer = name if path.name != "__init__.py" else f"{name}._"
        edges[name] = {t for t in imported(tree(path).body, importer) if t in modules and t != name
                       and not name.startswith(t + ".")}  # a module's own parents run first, not a cycle
    state: dict[str, int] = {}

    def visit(node: str, trail: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(edges[node]):
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join(trail[trail.index(nxt):] + [node, nxt])
                                     if nxt in trail else f"import cycle through {node} -> {nxt}")
            if nxt not in state:
                visit(nxt, trail + [node])
        state[node] = 2

    for name in sorted(modules):
        if name not in state:
            visit(name, [])


def test_module_sizes():
    lines = {name: len(path.read_text(encoding="utf-8").splitlines()) for name, path in all_modules().items()}
    assert not {n: c for n, c in lines.items() if c > 400}, "modules over 400 lines"
    stages = {n: c for n, c in lines.items() if n.startswith("toolpath.stages.") and c > 100}
    assert not stages, f"stage modules over 100 lines: {stages}"


def test_every_package_says_what_it_owns():
    for init in PACKAGE.glob("*/__init__.py"):
        doc = ast.get_docstring(tree(init))
        assert doc and len(doc) > 40, f"{init.parent.name}/__init__.py has no docstring saying what it owns"
