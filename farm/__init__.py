"""Scenario Farm: guaranteed safety assurance of automated-driving controllers by
scenario sampling, on a Ray farm. The Python API (``farm.api``):

    quantify(config, out=None, ...)  -> QuantifyResult   find the maximal safe set
    validate(config, out=None, ...)  -> Certificate      certify a claimed domain
    compare(directory_or_result)     -> dict             against the reference safe set
    export_openscenario(directory)   -> dict             failing runs and the set as OpenSCENARIO
    open_campaign(directory)         -> QuantifyResult   a finished campaign
    overlay([dir1, dir2], path)      -> Path             campaigns on the same slices
    load_config(source, **overrides) -> Config           TOML path or string, dict

Results: ``SafeSet`` (the boxes: contains, volumes, result_hash, Parquet), ``Summary``
(summary.json) and ``Certificate`` (certificate.json), frozen dataclasses.

Runtime pieces: config, executors (in-process and Ray), campaign storage, CLI.
"""

from coordinator.safe_set import SafeSet
from farm.api import (Certificate, QuantifyResult, compare, export_openscenario, load_config, open_campaign, overlay,
                      quantify, validate)
from farm.summary import Summary
from scenarios.version import __version__

__all__ = ["Certificate", "QuantifyResult", "SafeSet", "Summary", "__version__", "compare", "export_openscenario",
           "load_config",
           "open_campaign", "quantify", "overlay", "validate"]
