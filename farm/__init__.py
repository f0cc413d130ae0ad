"""Scenario Farm: guaranteed safety assurance of automated-driving controllers by
scenario sampling, on a Ray farm. The Python API (``farm.api``):

    quantify(config, out=None, ...)  -> QuantifyResult   find the maximal safe set
    validate(config, out=None, ...)  -> Certificate      certify a claimed domain
    compare(directory_or_result)     -> dict             against the reference safe set
    export_openscenario(directory)   -> dict             failing runs and the set as OpenSCENARIO
    open_campaign(directory)         -> QuantifyResult   a finished campaign
    overlay([dir1, dir2], path)      -> Path             campaigns on the same slices
    plan(config, out, workers=[...]) -> dict             time to the result per worker count (virtual farm)
    estimate(directory, config=None, ...) -> EstimateReport   P(failure) under a distribution D, beside the set
    load_config(source, **overrides) -> Config           TOML path or string, dict

Results: ``SafeSet`` (the boxes: contains, volumes, result_hash, Parquet), ``Summary``
(summary.json) and ``Certificate`` (certificate.json), frozen dataclasses.

Runtime pieces: config, executors (in-process and Ray), campaign storage, CLI.
"""

__all__ = ["Certificate", "EstimateReport", "QuantifyResult", "SafeSet", "Summary", "__version__", "compare",
           "estimate", "export_openscenario",
           "load_config", "open_campaign", "plan", "quantify", "overlay", "validate"]


def __getattr__(name: str):
    # the API is imported when first asked for, not with the package: the CLI's own
    # modules (farm.cli.commands, farm.cli.exits) load in a fraction of a second, so its signal
    # handlers and error lines are in place before pydantic, scipy and the coordinator load
    if name in __all__:
        from farm import lazy  # (farm/lazy.py: every module imported when first used)

        if name == "__version__":  # not with the package: it would load the scenarios package (numpy)
            from scenarios.version import __version__

            return __version__
        return getattr(lazy.api, name)
    raise AttributeError(f"module 'farm' has no attribute {name!r}")
