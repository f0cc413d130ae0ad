"""Checkpoint journal (farm/directory/journal.py): what a reader gets, and that reading changes
nothing on disk while the owner's load tidies up."""

from types import SimpleNamespace

import numpy as np
import pytest

from farm.directory.journal import Journal
from farm.directory.storage import CampaignError


def _saved(tmp_path):
    journal = Journal(tmp_path)
    grow_a, grow_b = np.arange(6.0).reshape(3, 2), np.arange(2, dtype=np.int32)
    journal.save({"a": grow_a, "b": grow_b, "flags": np.array([1, 0])}, {"a", "b"}, 0, {})
    grow_b = np.arange(5, dtype=np.int32)  # only b grows: the second segment holds b alone
    journal.save({"a": grow_a, "b": grow_b, "flags": np.array([1, 1])}, {"a", "b"}, 0, {})
    return grow_a, grow_b


def test_read_returns_what_load_returns_and_only_the_names_asked(tmp_path):
    a, b = _saved(tmp_path)
    loaded, _ = Journal(tmp_path).load()
    assert np.array_equal(loaded["a"], a) and np.array_equal(loaded["b"], b)
    assert np.array_equal(loaded["flags"], [1, 1])
    everything, _ = Journal(tmp_path).read()
    assert everything.keys() == loaded.keys()
    some, meta = Journal(tmp_path).read(["a", "flags", "not saved"])
    assert set(some) == {"a", "flags"} and np.array_equal(some["a"], a)
    assert meta["append_only"] == ["a", "b"]


def test_its_size_is_the_checkpoint_and_its_segments(tmp_path):
    assert Journal(tmp_path).size_bytes() == 0  # none yet
    _saved(tmp_path)
    segments = sorted((tmp_path / "checkpoint").glob("segment-*.npz"))
    (tmp_path / "checkpoint" / "notes.txt").write_text("x" * 1000)  # not the journal's: not counted
    want = (tmp_path / "checkpoint.npz").stat().st_size + sum(f.stat().st_size for f in segments)
    assert len(segments) == 2 and Journal(tmp_path).size_bytes() == want


def test_read_skips_segments_without_the_names_asked_and_checks_the_others(tmp_path):
    _saved(tmp_path)
    second = sorted((tmp_path / "checkpoint").glob("segment-*.npz"))[1]
    second.write_bytes(second.read_bytes()[:-1] + b"x")  # b's rows damaged
    assert set(Journal(tmp_path).read(["a"])[0]) == {"a"}
    with pytest.raises(CampaignError, match="sha256"):
        Journal(tmp_path).read(["b"])


def test_reading_leaves_unlisted_segments_loading_removes_them(tmp_path):
    _saved(tmp_path)
    # a segment a running campaign has written and not listed yet (or kill -9 debris)
    fresh = tmp_path / "checkpoint" / "segment-000099.npz"
    fresh.write_bytes(b"not listed yet")
    Journal(tmp_path).read()
    Journal(tmp_path).read(["a"])
    assert fresh.exists()
    Journal(tmp_path).load()  # the owner, resuming: debris goes
    assert not fresh.exists()


def test_a_finished_certified_campaign_checkpoints_its_whole_certificates_then_lets_them_go(tmp_path, monkeypatch):
    # the reverse index goes before the last checkpoint, the entries after it: the
    # checkpoint still holds every entry, and certifies every alive centre of the result
    from coordinator.checked_centres import CheckedCentres
    from farm import config as config_mod
    from farm.jobs import quantification

    parts = []
    monkeypatch.setattr(quantification, "finish", lambda cfg, out, p: parts.append(p) or SimpleNamespace(result_hash=""))
    cfg = config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "adversarial"},
        "quantify": {"delta0": 4.0, "delta_min": 1.0, "epsilon": 0.01, "beta": 0.1, "horizon": 30, "refine": "all"},
        "farm": {"executor": "local", "batch_size": 256, "seed": 1}})
    quantification.run(cfg, tmp_path / "c")
    algo = parts[0]["total"].algorithm
    assert algo.certifying and algo.enumerates
    state, _ = Journal(tmp_path / "c").read(["algo.cert.vertex", "algo.cert.offsets", "algo.cert.witness",
                                             "algo.cert.valid", "algo.vertices.alive"])
    assert state["algo.cert.offsets"][-1] == len(state["algo.cert.witness"]) > 0
    assert len(state["algo.cert.vertex"]) == len(state["algo.cert.valid"]) == len(state["algo.cert.offsets"]) - 1
    alive = state["algo.vertices.alive"].astype(bool)
    saved = CheckedCentres.from_state({k[len("algo."):]: v for k, v in state.items() if k.startswith("algo.cert.")})
    assert saved.certified(len(alive))[alive].all()
    assert np.array_equal(algo.checked.certified(len(alive)), saved.certified(len(alive)))
    with pytest.raises(RuntimeError, match="released"):
        algo.state()
