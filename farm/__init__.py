"""Scenario Farm runtime: seeds, batching, executors, Ray actors, CLI, campaign storage."""

__version__ = "0.1.0"
