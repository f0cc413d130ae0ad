"""The SUMO back end (``scenario.backend = "sumo"``): the SV is a real SUMO vehicle
driven by SUMO's own car-following model, a true black box. See ``backend.py`` and
docs/backends.md.

``config.py`` checks the ``[scenario.sumo]`` table without a simulation; only
``simulation.py`` imports libsumo, and only when the back end is chosen.
"""

from scenarios.sumo.config import SumoConfig, parse_config

__all__ = ["SumoConfig", "parse_config"]
