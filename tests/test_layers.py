"""Layers point one way: scenarios <- coordinator <- farm. Checked on the source's
imports (including imports inside functions), so a shortcut cannot creep in."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALLOWED = {"scenarios": {"scenarios"}, "coordinator": {"scenarios", "coordinator"},
           "farm": {"scenarios", "coordinator", "farm"}}


@pytest.mark.parametrize("package", list(ALLOWED))
def test_a_package_imports_only_its_own_layer_and_those_below(package):
    wrong = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 else []
            for name in names:
                top = name.split(".")[0]
                if top in ALLOWED and top not in ALLOWED[package]:
                    wrong.append(f"{path.relative_to(ROOT)}:{node.lineno} imports {name}")
    assert not wrong, "\n".join(wrong)
