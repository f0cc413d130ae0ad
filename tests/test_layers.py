"""Layers point one way: scenarios <- coordinator <- farm, and inside them the packages in
their order. Checked on the source's imports (including imports inside functions, and the
modules farm/lazy.py imports when first used), so a shortcut cannot creep in."""

import ast
from pathlib import Path

import pytest

from source_imports import ROOT, source_imports

ALLOWED = {"scenarios": {"scenarios"}, "coordinator": {"scenarios", "coordinator"},
           "farm": {"scenarios", "coordinator", "farm"}}

# farm's packages, lowest first: each imports only itself and those before it
FARM_ORDER = ["config", "lazy", "execution", "ray_runtime", "directory", "reports", "openscenario", "jobs", "api",
              "cli"]
# the executor factory names every kind of executor (imported when chosen): Ray's is above it
LATE_BINDINGS = {("farm/execution/factory.py", "ray_runtime")}


@pytest.mark.parametrize("package", list(ALLOWED))
def test_a_package_imports_only_its_own_layer_and_those_below(package):
    wrong = []
    for path, line, name in source_imports(package):
        top = name.split(".")[0]
        if top in ALLOWED and top not in ALLOWED[package]:
            wrong.append(f"{path}:{line} imports {name}")
    assert not wrong, "\n".join(wrong)


def _farm_part(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "farm" or len(parts) < 2:
        return None
    return parts[1] if parts[1] in FARM_ORDER else "farm"


def _farm_imports():
    """(file, line, farm package imported) for every import of a farm module by farm's own
    source: ``from farm import x`` names farm.x; ``lazy.x`` the module farm/lazy.py maps x to."""
    import importlib

    lazy_table = importlib.import_module("farm.lazy").MODULES
    for path in sorted((ROOT / "farm").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            modules = []
            if isinstance(node, ast.Import):
                modules = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                modules = [f"{node.module}.{a.name}" if node.module == "farm" else node.module for a in node.names]
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "lazy":
                modules = [lazy_table.get(node.attr, "")]
            for module in modules:
                part = _farm_part(module)
                if part is not None:
                    yield path.relative_to(ROOT), node.lineno, part


def test_farm_packages_import_only_themselves_and_those_below():
    wrong = []
    for path, line, part in _farm_imports():
        own = path.parts[1] if len(path.parts) > 2 else path.stem
        if own not in FARM_ORDER or part == "farm" or (str(path), part) in LATE_BINDINGS:
            continue
        if FARM_ORDER.index(part) > FARM_ORDER.index(own):
            wrong.append(f"{path}:{line} ({own}) imports farm.{part}")
    assert not wrong, "\n".join(wrong)


def test_only_the_driver_drives():
    """coordinator/driver/ imports the rest of the coordinator; nothing of the coordinator
    imports the driver but its package front and its conformance suite."""
    allowed = {Path("coordinator/__init__.py"), Path("coordinator/testing.py")}
    wrong = [f"{path}:{line} imports {name}" for path, line, name in source_imports("coordinator")
             if name.startswith("coordinator.driver") and path.parts[1] != "driver" and path not in allowed]
    assert not wrong, "\n".join(wrong)
