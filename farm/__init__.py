"""Scenario Farm runtime: seeds, batching, executors, Ray actors, CLI, campaign storage."""

from scenarios.version import __version__

__all__ = ["__version__"]
