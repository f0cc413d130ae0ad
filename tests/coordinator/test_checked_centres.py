"""Deterministic certification's bookkeeping against a brute-force model: an entry holds
until one of its witnesses is killed; a centre is certified while it has a valid entry;
a checkpoint round trip and a released reverse index keep all of it."""

import numpy as np
import pytest

from coordinator.checked_centres import CheckedCentres, _compress, _merge, _SortedRuns


@pytest.mark.parametrize("final_size", [_SortedRuns.FINAL_SIZE, 500])
def test_certificates_match_a_brute_force_model_through_adds_kills_and_a_round_trip(final_size, monkeypatch):
    # a small FINAL_SIZE compresses runs early (as 83 M witnesses do at the default)
    monkeypatch.setattr(_SortedRuns, "FINAL_SIZE", final_size)
    rng = np.random.default_rng(4)
    frozen = 0
    cert = CheckedCentres()
    model: list[tuple[int, set[int], bool]] = []  # (vertex, witnesses, valid)
    vertices = 3000
    for step in range(400):
        if rng.random() < 0.7:  # a chunk's quiet runs certify their start centres
            k = int(rng.integers(1, 40))
            starts = rng.integers(0, vertices, k)
            counts = rng.integers(0, 12, k)
            witnesses = rng.integers(0, vertices, int(counts.sum()))
            offsets = np.concatenate([[0], np.cumsum(counts)])
            cert.add(starts, offsets, witnesses)
            for i, v in enumerate(starts):
                model.append((int(v), set(witnesses[offsets[i]:offsets[i + 1]].tolist()), True))
        else:  # a prune
            killed = rng.integers(0, vertices, int(rng.integers(1, 60)))
            cert.invalidate(killed)
            dead = set(killed.tolist())
            model = [(v, w, ok and not (w & dead)) for v, w, ok in model]
        if step % 50 == 49:  # a checkpoint and resume (the reverse index is built when first needed)
            cert = CheckedCentres.from_state({k: v.copy() for k, v in cert.state().items()})
        if cert._reverse is not None:
            frozen = max(frozen, cert._reverse.tiers.count(_SortedRuns.FINAL))
        if step % 70 == 69:  # a finished campaign drops the reverse index; it comes back if needed
            cert.release_index()
        expected = np.zeros(vertices, dtype=bool)
        for v, _, ok in model:
            expected[v] |= ok
        assert np.array_equal(cert.certified(vertices), expected)
    valid = np.array([ok for _, _, ok in model])
    assert np.array_equal(cert.state()["cert.valid"], valid)
    assert 0.1 < valid.mean() < 0.9  # both kinds of entries were exercised
    assert (frozen >= 8) == (final_size < 10_000)  # compressed runs were exercised (only when small)


@pytest.mark.parametrize("final_size", [_SortedRuns.FINAL_SIZE, 300])
def test_reverse_index_finds_every_value_of_every_key(final_size, monkeypatch):
    # every key that starts or ends a run, and keys absent from some runs, are asked
    monkeypatch.setattr(_SortedRuns, "FINAL_SIZE", final_size)
    rng = np.random.default_rng(7)
    index, keys_all, values_all = _SortedRuns(), [], []
    next_value = 0
    for _ in range(150):
        k = int(rng.integers(1, 60))
        keys = rng.integers(0, 2000, k)
        values = np.arange(next_value, next_value + k)
        next_value += k
        index.add(keys, values)
        keys_all.append(keys)
        values_all.append(values)
        stored_keys, stored_values = np.concatenate(keys_all), np.concatenate(values_all)
        ends = [run[0][[0, -1]] if isinstance(run, tuple) else (run[[0, -1]] >> 32) for run in index.runs]
        asked = np.unique(np.concatenate([rng.integers(0, 2100, 40), *ends]))
        found = np.sort(index.find(asked))
        assert np.array_equal(found, np.sort(stored_values[np.isin(stored_keys, asked)]))
    assert (index.tiers.count(_SortedRuns.FINAL) >= 3) == (final_size < 10_000)


def test_released_certificates_still_say_which_centres_are_certified_and_refuse_the_rest():
    rng = np.random.default_rng(11)
    cert = CheckedCentres()
    for _ in range(30):
        k = int(rng.integers(1, 30))
        counts = rng.integers(1, 8, k)
        cert.add(rng.integers(0, 500, k), np.concatenate([[0], np.cumsum(counts)]),
                 rng.integers(0, 500, int(counts.sum())))
    cert.invalidate(rng.integers(0, 500, 40))
    before = cert.certified(600)
    assert 0 < before.sum() < 500
    cert.release()
    assert np.array_equal(cert.certified(600), before)
    assert np.array_equal(cert.certified_at(np.arange(600)), before)
    for call in (cert.state, lambda: cert.invalidate(np.array([1])),
                 lambda: cert.add(np.array([1]), np.array([0, 1]), np.array([2]))):
        with pytest.raises(RuntimeError, match="released"):
            call()


def test_compression_reads_keys_and_values_of_every_pair():
    # keys recur (as witnesses do) and reach the largest allowed; values span the int32 range
    keys = np.concatenate([np.random.default_rng(3).integers(0, 800, 4990), np.full(10, 2**31 - 1)])
    values = np.random.default_rng(4).integers(0, 2**31, 5000)
    pairs = np.sort((keys.astype(np.int64) << 32) | values)
    distinct, starts, stored = _compress(pairs)
    assert distinct.dtype == stored.dtype == np.int32
    assert np.array_equal(np.repeat(distinct, np.diff(starts)), pairs >> 32)
    assert np.array_equal(stored, pairs & 0xFFFFFFFF)
    assert len(distinct) == len(np.unique(keys)) < 1000


def test_a_merge_is_the_sorted_union_of_its_parts_and_empties_them():
    rng = np.random.default_rng(5)
    parts = [np.sort(rng.integers(0, 2**62, int(rng.integers(0, 300)))) for _ in range(4)]
    expected = np.sort(np.concatenate(parts))
    given = list(parts)
    assert np.array_equal(_merge(given), expected)
    assert given == []
