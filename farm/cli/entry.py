"""The ``scenario-farm`` command's first lines (also ``python -m farm``): stop signals are
held from here on (farm/jobs/signals.py ``hold_stops``), before the command's modules load
(farm/cli/commands.py), so that a stop in its first instants ends with exit 130 ("stopped"),
as the exit table says. Nothing heavy is imported before that."""

from farm.jobs.signals import hold_stops


def run():
    hold_stops()
    from farm.cli.commands import run as command

    command()
