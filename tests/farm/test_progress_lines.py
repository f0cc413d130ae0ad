"""Progress lines a job log gets between the last run and the result (no subprocess)."""

import io

from farm.reports.progress import Progress


def test_the_end_of_the_runs_is_announced_unless_quiet():
    log = io.StringIO()  # not a terminal: plain lines, as under `ray job logs`
    Progress(stream=log).close()
    assert log.getvalue() == "scenario-farm: all runs done; writing safe_set.parquet, summary.json and plots/\n"
    log = io.StringIO()
    Progress(stream=log, mode="quiet").close()
    assert log.getvalue() == ""


def test_a_certifying_campaign_says_closing_or_which_check_and_what_certification_cost():
    # a real (small) certified campaign, its plain progress lines captured as a job log has them
    from farm import config as config_mod
    from farm.jobs.quantification import run
    from small_campaign import lead_follow_toml

    import tempfile
    from pathlib import Path

    log = io.StringIO()
    with tempfile.TemporaryDirectory() as d:
        summary = run(config_mod.parse(lead_follow_toml()), Path(d) / "q", progress=Progress(stream=log, interval=0.0))
    lines = log.getvalue().splitlines()
    assert any(" closing " in line and "(certification " in line for line in lines), lines
    assert any(" check 1 " in line for line in lines), lines
    assert summary["runs_certification"] > 0 and summary["certification_attempts"] >= 1


def test_a_check_line_shows_the_violations_it_tolerated_so_far():
    from farm.reports.progress import _counter

    status = {"certification_phase": "check", "certification_attempts": 2, "n_eps_counter": 600,
              "n_eps_needed": 7456, "runs_certification": 9000}
    assert _counter(status).startswith("check 2 600/7,456 ")
    assert _counter({**status, "certification_check_violations": 2}).startswith("check 2 (2 tolerated) 600/7,456 ")
