"""Every third-party package the code imports is declared in pyproject.toml (pydantic
arrived through Ray and was not), and the version has one source."""

import sys
import tomllib

from source_imports import ROOT, source_imports

PACKAGES = ("farm", "coordinator", "scenarios")
# import name -> distribution name, where they differ
DISTRIBUTION = {"yaml": "pyyaml"}


def imported_packages() -> dict[str, str]:
    """Third-party distribution -> a file that imports it."""
    found = {}
    for package in PACKAGES:
        for path, _, name in source_imports(package):
            top = name.split(".")[0]
            if top not in sys.stdlib_module_names and top not in PACKAGES:
                found.setdefault(DISTRIBUTION.get(top, top), str(path))
    return found


def declared() -> set[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    specs = project["dependencies"] + [d for extra in project["optional-dependencies"].values() for d in extra]
    names = set()
    for spec in specs:
        name = spec.split(";")[0]
        for stop in "[<>=! ":
            name = name.split(stop)[0]
        names.add(name.strip().lower())
    return names


def test_every_third_party_import_is_declared():
    missing = {name: where for name, where in imported_packages().items() if name.lower() not in declared()}
    assert not missing, f"imported but not declared in pyproject.toml: {missing}"
    assert "pydantic" in imported_packages()  # the check sees what it checks


def test_the_version_has_one_source():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "scenarios.version.__version__"}
    import subprocess

    from scenarios.version import __version__

    out = subprocess.run([sys.executable, "-m", "farm", "--version"], capture_output=True, text=True, cwd=ROOT)
    assert out.stdout.strip() == f"scenario-farm {__version__}", out.stderr


def test_a_cli_command_starts_without_the_heavy_imports_it_may_not_need():
    """A refused config, `status` or `--help` pays the CLI's imports; scipy.stats alone was
    1.6 s of them (docs/benchmarks.md), Ray and matplotlib more. They load where used."""
    import subprocess
    import sys

    heavy = ("scipy.stats", "ray", "matplotlib", "pandas", "networkx", "mcap", "libsumo")
    code = ("import sys; import farm.cli.commands, farm.api; "
            f"print(','.join(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", out.stdout
