"""Checkpoint journal (farm/journal.py): what a reader gets, and that reading changes
nothing on disk while the owner's load tidies up."""

import numpy as np
import pytest

from farm.journal import Journal
from farm.storage import CampaignError


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
