"""The errors this tool raises on purpose: one root, and beneath it whose fault it is.

    FarmError
    ├── UserError             the input: fix it and run again (CLI exit 2)
    │   ├── ConfigError       a config value or a command-line flag, named with its allowed range
    │   ├── CampaignError     a campaign directory, or a file in it, that cannot be used as asked
    │   ├── DataError         a file given as input (a safe set, a recording) that is not what it should be
    │   └── ScenarioError     user code (scenario, back end, feedback policy) that raised or misbehaved
    └── InfrastructureError   what runs the campaign failed: Ray, a disk (CLI exit 4)

``Stopped`` is no error: a campaign stopped by a signal, checkpointed (CLI exit 130).
Anything else escaping is a bug of this tool (exit 3). Every message is one line that
names the field, file or sample index and, where there is one, the allowed range.
Errors that were a ``ValueError`` before stay one (callers may catch that).
"""

from __future__ import annotations


class FarmError(Exception):
    """Root of the errors this tool raises on purpose."""


class UserError(FarmError):
    """The user's input is wrong: a config, a flag, a directory, their own code."""


class ConfigError(UserError, ValueError):
    """A config value or a command-line flag: names the field and the allowed range."""


class CampaignError(UserError):
    """A campaign directory (or a file in it) that cannot be used as asked; nothing was changed."""


class DataError(UserError, ValueError):
    """An input file (a safe set, a recording) whose content is not what it should be."""


class ScenarioError(UserError):
    """User code produced something no verdict can be drawn from: it raised, or returned
    NaN or the wrong shape. Names the scenario (or policy) and the sample index."""


class InfrastructureError(FarmError):
    """What runs the campaign failed (Ray lost, a full disk): the input may be fine, and a
    campaign's last checkpoint stands (``resume`` continues it)."""


class Stopped(Exception):
    """A campaign was stopped by a signal; it is checkpointed and can be resumed."""
