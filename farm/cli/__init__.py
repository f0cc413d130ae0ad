"""The command line: ``scenario-farm`` and ``python -m farm``, its exit codes and its stderr."""
