"""Modules imported when first used, in one table (as Ray Tune's ``search/__init__.py``
keeps its searchers): the optional or heavy ones that a command which does not need them
must not pay for, and what the CLI loads only once its signal handlers and error lines
are in place. ``lazy.plots`` is ``farm.reports.plots``, imported at the first access.

Measured import times are in docs/benchmarks.md ("Imports"). Every other module of this
package imports what it uses at its top.
"""

from __future__ import annotations

import importlib

MODULES = {
    "api": "farm.api",  # the Python API (pydantic, scipy and the coordinator behind it)
    "handlers": "farm.cli.handlers",  # the CLI's commands, loaded after its handlers are set
    "ray": "ray",  # the Ray executor only
    "ray_executor": "farm.ray_runtime.executor",
    "ray_session": "farm.ray_runtime.session",
    "local_executor": "farm.execution.local",
    "virtual_executor": "farm.execution.virtual",
    "plots": "farm.reports.plots",  # matplotlib
    "html": "farm.reports.html",
    "compare": "farm.reports.compare",  # the reference sets
    "networkx": "networkx",  # the exploration graph as GraphML
    "rerun": "farm.jobs.rerun",  # MCAP recordings read back
    "recording": "farm.directory.recording",  # mcap
    "falsify": "farm.jobs.falsify",
    "planning": "farm.jobs.planning",
    "openscenario": "farm.openscenario.export",
    "openscenario_ranges": "farm.openscenario.ranges",
    "validation": "farm.jobs.validation",
    "quantification": "farm.jobs.quantification",
    "estimation": "farm.jobs.estimation",
    "estimate_figure": "farm.reports.estimate_figure",  # matplotlib
    "pyarrow_dataset": "pyarrow.dataset",  # the ledger read as one table
    "rich_console": "rich.console",  # the live progress line, on a terminal only
    "rich_progress": "rich.progress",
    "ray_constants": "ray._private.ray_constants",
    "ray_services": "ray._private.services",
    "ray_utils": "ray._private.utils",
}

__all__ = sorted(MODULES)


def __getattr__(name: str):
    if name in MODULES:
        module = importlib.import_module(MODULES[name])
        globals()[name] = module  # the next access is a plain attribute
        return module
    raise AttributeError(f"module 'farm.lazy' has no attribute {name!r}")
