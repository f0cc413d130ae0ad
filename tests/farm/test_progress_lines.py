"""Progress lines a job log gets between the last run and the result (no subprocess)."""

import io

from farm.progress import Progress


def test_the_end_of_the_runs_is_announced_unless_quiet():
    log = io.StringIO()  # not a terminal: plain lines, as under `ray job logs`
    Progress(stream=log).close()
    assert log.getvalue() == "scenario-farm: all runs done; writing safe_set.parquet, summary.json and plots/\n"
    log = io.StringIO()
    Progress(stream=log, mode="quiet").close()
    assert log.getvalue() == ""
