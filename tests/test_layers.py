"""Layers point one way: scenarios <- coordinator <- farm. Checked on the source's
imports (including imports inside functions), so a shortcut cannot creep in."""

import pytest

from source_imports import source_imports

ALLOWED = {"scenarios": {"scenarios"}, "coordinator": {"scenarios", "coordinator"},
           "farm": {"scenarios", "coordinator", "farm"}}


@pytest.mark.parametrize("package", list(ALLOWED))
def test_a_package_imports_only_its_own_layer_and_those_below(package):
    wrong = []
    for path, line, name in source_imports(package):
        top = name.split(".")[0]
        if top in ALLOWED and top not in ALLOWED[package]:
            wrong.append(f"{path}:{line} imports {name}")
    assert not wrong, "\n".join(wrong)
