"""scenario-farm plan: one campaign on the virtual farm per worker count, the times side by
side (plan.json, plan.png), and never a directory it was not asked to replace."""

import json
import subprocess
import sys

from farm import api
from farm.directory.storage import CampaignDir
from farm.reports.summary import Summary
from small_campaign import lead_follow_toml


def cli(*args):
    return subprocess.run([sys.executable, "-m", "farm", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def test_a_plan_runs_every_count_and_each_is_the_real_campaign(tmp_path):
    out = tmp_path / "plan"
    result = api.plan(lead_follow_toml(), out=out, workers=[16, 1, 4], run_time=0.5)
    assert json.loads((out / "plan.json").read_text()) == result
    rows = result["rows"]
    assert [r["workers"] for r in rows] == [1, 4, 16]
    for r in rows:  # each count is a normal campaign directory, on the virtual farm, with the run time asked
        summary = Summary.read(out / f"workers-{r['workers']}")
        assert summary["result_hash"] == r["result_hash"]
        assert summary["virtual_elapsed_s"] == r["virtual_elapsed_s"]
        frozen = CampaignDir(out / f"workers-{r['workers']}").frozen_config().farm
        assert (frozen.executor, frozen.workers, frozen.virtual.run_time) == ("virtual", r["workers"], 0.5)
    assert result["same_result"] and len({r["result_hash"] for r in rows}) == 1
    times = [r["virtual_elapsed_s"] for r in rows]
    assert times[0] > times[1] > times[2]  # more workers of 0.5 s runs: sooner
    assert rows[0]["speed_up"] == 1.0 and rows[2]["speed_up"] == round(times[0] / times[2], 2)
    assert result["recommended_workers"] in (4, 16)
    # where the time went: one worker of 0.5 s runs is always busy, so the coordinator waits
    # for its runs nearly all the time; at every count the waits and its CPU are shares of it
    assert rows[0]["waiting_share"] > 0.9
    for r in rows:
        assert 0 < r["coordinator_share"] < 1 and 0 <= r["waiting_share"] + r["coordinator_share"] <= 1
    assert (out / "plan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plan_says_what_is_wrong_and_replaces_only_a_plan(tmp_path):
    # what a plan refuses and replaces, not what it runs: the campaign without certification
    (tmp_path / "c.toml").write_text(lead_follow_toml(quantify_extra="certify = false\n"))
    bad = cli("plan", tmp_path / "c.toml", "--out", tmp_path / "p", "--workers", "0", "--quiet")
    assert bad.returncode == 2 and "--workers: 0 is out of range; allowed [1, 4096]" in bad.stderr
    assert not (tmp_path / "p").exists()  # refused before anything was written
    bad = cli("plan", tmp_path / "c.toml", "--out", tmp_path / "p", "--run-time", "-1", "--quiet")
    assert bad.returncode == 2 and "--run-time" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1

    ok = cli("plan", tmp_path / "c.toml", "--out", tmp_path / "p", "--workers", "1", "2", "--quiet")
    assert ok.returncode == 0, ok.stderr
    assert "one result at every count: yes" in ok.stdout
    again = cli("plan", tmp_path / "c.toml", "--out", tmp_path / "p", "--workers", "2", "--quiet")
    assert again.returncode == 2 and "pass --force" in again.stderr
    assert (tmp_path / "p" / "workers-1").is_dir()  # the refused plan left the old one whole

    # a quantify campaign is not a plan: --force does not replace it
    campaign = tmp_path / "p" / "workers-1"
    before = sorted(p.name for p in campaign.iterdir())
    refused = cli("plan", tmp_path / "c.toml", "--out", campaign, "--workers", "2", "--force", "--quiet")
    assert refused.returncode == 2 and "not a plan" in refused.stderr
    assert sorted(p.name for p in campaign.iterdir()) == before

    replaced = cli("plan", tmp_path / "c.toml", "--out", tmp_path / "p", "--workers", "3", "--force", "--quiet")
    assert replaced.returncode == 0, replaced.stderr
    assert sorted(p.name for p in (tmp_path / "p").iterdir() if p.is_dir()) == ["workers-3"]
