"""summary.json through farm.reports.summary.Summary: a real campaign's file reads back to the same
keys in the same order and writes back byte for byte (its sides too); an older file
(the first writer's keys, and keys this reader does not know) still reads, and every
reader of a campaign directory takes it; a file that is no summary is a one-line error."""

import html
import io
import json
import shutil

import pytest

from coordinator.safe_set import SafeSet
from farm import api, config as config_mod
from farm.jobs.quantification import run
from farm.reports.html import write_html
from farm.reports.status import describe
from farm.directory.storage import CampaignError
from farm.reports.progress import Progress
from farm.reports.summary import SideSummary, Summary
from farm.reports.truncations import lines as truncation_lines
from farm.reports.truncations import side_lines
from scenarios.fleet3 import Fleet3

# keys the first summary.json writer (before certification rounds) did not write
LATER_KEYS = ("certification_attempts", "n_eps_final", "startup_s", "guarantee_formal", "guarantee_formal_lead_side",
              "guarantee_formal_rear_side")


@pytest.fixture(scope="module")
def fleet3(tmp_path_factory):
    """A small real fleet3 campaign: a total and two sides."""
    out = tmp_path_factory.mktemp("fleet3") / "c"
    cfg = config_mod.normalize({"scenario": {"name": "fleet3", "sv_policy": "brake"}, "actions": {"mode": "adversarial"},
                                "quantify": {"delta0": 3.0, "delta_min": 3.0, "epsilon": 0.01, "beta": 0.1,
                                             "horizon": 30},
                                "farm": {"executor": "local", "batch_size": 256}})
    returned = run(cfg, out, resume=False, progress=Progress(stream=STARTED))
    return out, returned


STARTED = io.StringIO()  # the fleet3 campaign's progress lines


def test_sides_are_said_at_the_start_and_another_sides_failure_is_no_truncation_at_the_end(fleet3):
    out, summary = fleet3
    assert "sides: scenario 'fleet3' declares sides lead, rear: 3 campaigns" in STARTED.getvalue()
    assert "quantify.sides = false" in STARTED.getvalue()
    # a side's study that ends runs on the other side's failure facet counts them apart, never as truncations
    assert summary.side_failures is not None and not {"p10 < 5", "p20 > -5"} & set(summary.truncations)
    assert set(summary.side_failures.get("p10 < 5", {})) <= {"rear"}
    assert set(summary.side_failures.get("p20 > -5", {})) <= {"lead"}


def test_the_end_lines_call_another_sides_failure_what_it_is():
    base = {"scenario": "fleet3", "algorithm": "spe", "boxes": 1, "result_hash": "h", "guarantee": "g"}
    summary = Summary.from_json({**base, "runs_committed": 10_000, "truncations": {"v1 > 6": 300},
                                 "side_failures": {"p20 > -5": {"lead": 412}, "p10 < 5": {"rear": 20}}})
    assert truncation_lines(summary) == ["300 runs left through v1 > 6 (truncated, counted safe; 3.0% of committed runs)"]
    assert side_lines(summary) == ["412 runs of the lead side's study reached p20 > -5, another side's failure (not "
                                   "one of the lead side, whose study leaves that facet out; the total counts it; "
                                   "4.1% of committed runs)"]  # 0.2 %: not said


def test_a_real_summary_reads_back_key_for_key_and_writes_back_byte_for_byte(fleet3, tmp_path):
    out, returned = fleet3
    text = (out / "summary.json").read_text()
    summary = Summary.read(out)
    assert summary == returned and summary.extra == {}
    assert list(summary.to_json().items()) == list(json.loads(text).items())  # keys, values and order
    summary.write(tmp_path)
    assert (tmp_path / "summary.json").read_text() == text
    assert set(summary.sides) == {"lead", "rear"}
    for label, side in summary.sides.items():
        on_file = SafeSet.from_parquet(out / f"safe_set_{label}_side.parquet", Fleet3.state_names)
        assert side.result_hash == on_file.result_hash and side.volume == summary[f"volume_{label}_side"]
        assert side.guarantee.startswith("Every scenario") and side.guarantee_formal.startswith("Phi is")
    total = SafeSet.from_parquet(out / "safe_set.parquet", Fleet3.state_names)
    assert (summary.boxes, summary.result_hash, summary.delta_final) == (len(total), total.result_hash, total.finest)
    assert summary["result_hash"] == summary.result_hash  # the JSON key, for code written against the dict


def older(directory, tmp_path):
    """A copy of the campaign whose summary.json is as the first writer wrote it, with
    two keys a newer writer might add."""
    copy = tmp_path / "older"
    shutil.copytree(directory, copy)
    data = json.loads((copy / "summary.json").read_text())
    for key in LATER_KEYS:
        del data[key]
    data["future_figure"] = 1.5
    data["future_record"] = {"a": [1, 2]}
    (copy / "summary.json").write_text(json.dumps(data, indent=2))
    return copy, data


def test_an_older_summary_with_unknown_keys_reads_and_every_reader_takes_it(fleet3, tmp_path):
    out, returned = fleet3
    copy, data = older(out, tmp_path)
    summary = Summary.read(copy)
    assert summary.result_hash == returned.result_hash and summary.boxes == returned.boxes
    assert (summary.guarantee_formal, summary.startup_s, summary.certification_attempts) == ("", 0.0, 0)
    assert summary.sides["lead"] == SideSummary(volume=returned.sides["lead"].volume,
                                                volume_hull=returned.sides["lead"].volume_hull,
                                                result_hash=returned.sides["lead"].result_hash,
                                                guarantee=returned.sides["lead"].guarantee)
    assert summary.extra == {"future_figure": 1.5, "future_record": {"a": [1, 2]}}
    written = summary.to_json()
    assert list(written)[-2:] == ["future_figure", "future_record"] and written["future_figure"] == 1.5
    # the readers of a campaign directory: the API, status, the HTML report
    result = api.open_campaign(copy)
    assert result.summary == summary and result.guarantee == summary.guarantee and result.guarantee_formal == ""
    assert f"result hash {summary.result_hash}" in describe(copy)
    assert html.escape(summary.guarantee) in write_html(copy).read_text()


@pytest.mark.parametrize("change,message", [
    (lambda d: d.pop("result_hash"), "lacks result_hash"),
    (lambda d: d.update(boxes="many"), "boxes is 'many'; expected int"),
    (lambda d: d.update(converged="yes"), "converged is 'yes'; expected bool"),
    (lambda d: d.update(volume_union=True), "volume_union is True; expected int or float"),
    (lambda d: d.pop("volume_lead_side"), "side 'lead'.*lacks volume"),
])
def test_a_summary_that_lies_is_a_one_line_error_naming_the_key(fleet3, tmp_path, change, message):
    data = json.loads((fleet3[0] / "summary.json").read_text())
    change(data)
    (tmp_path / "summary.json").write_text(json.dumps(data))
    with pytest.raises(CampaignError, match=message) as err:
        Summary.read(tmp_path)
    assert "\n" not in str(err.value) and "summary.json" in str(err.value)


def test_no_summary_or_not_json_is_a_one_line_error(tmp_path):
    with pytest.raises(CampaignError, match="has not finished \\(no summary.json\\)"):
        Summary.read(tmp_path)
    (tmp_path / "summary.json").write_text("{not json")
    with pytest.raises(CampaignError, match="summary.json: not valid JSON"):
        Summary.read(tmp_path)
    (tmp_path / "summary.json").write_text("[1, 2]")
    with pytest.raises(CampaignError, match="holds a JSON list, not the object"):
        Summary.read(tmp_path)
