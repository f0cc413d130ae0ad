"""SafeSet: a union of l-inf boxes, each with its own half-width. Its hash is the one every
recorded result_hash used (checked on a real campaign's output), its volumes are exact
for mixed sizes (checked against a raster count), and safe_set.parquet round-trips,
mixed sizes included; a bad file is a one-line error."""

import hashlib
import itertools

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from scipy.spatial import ConvexHull

from coordinator.domain import Domain
from coordinator.safe_set import SafeSet, SafeSetError
from farm import config as config_mod
from farm.jobs.quantification import run
from scenarios.lead_follow import LeadFollow
from scenarios.streams import RunStreams
from scenarios.toy import Toy
from small_campaign import lead_follow_toml

NAMES = ("x", "y", "z")


def recorded_hash(centres: np.ndarray, half_width: float) -> str:
    """coordinator.results.result_hash as it was until SafeSet: the formula behind every
    result_hash recorded so far (README, docs)."""
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    order = np.lexsort(centres.T[::-1]) if len(centres) else np.zeros(0, dtype=np.int64)
    h = hashlib.sha256()
    h.update(np.float64(half_width).tobytes())
    h.update(np.ascontiguousarray(centres[order]).tobytes())
    return h.hexdigest()[:16]


def mixed_set(rng, n=3, boxes=80, aligned=True) -> SafeSet:
    """Boxes of half-widths 0.25, 0.5 and 1: on each size's own lattice (as refinement
    makes them), or anywhere on a 1/8 grid (ragged)."""
    widths = rng.choice([0.25, 0.5, 1.0], boxes)
    if aligned:
        centres = (rng.integers(0, 10, (boxes, n)) * 2 + 1) * widths[:, None]
    else:
        centres = rng.integers(0, 80, (boxes, n)) / 8.0
    return SafeSet(centres, widths, NAMES[:n] if n <= len(NAMES) else tuple(f"x{a}" for a in range(n)))


def raster_volume(safe_set: SafeSet, lo, hi, cell=1 / 8) -> float:
    """The cells of a grid every box face lies on, counted where some box covers them:
    the exact union volume (clipped to [lo, hi]) of boxes whose faces are on the grid."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    shape = np.round((hi - lo) / cell).astype(int)
    covered = np.zeros(shape, dtype=bool)
    for centre, width in zip(safe_set.centres, safe_set.half_widths):
        first = np.clip(np.round((centre - width - lo) / cell).astype(int), 0, shape)
        end = np.clip(np.round((centre + width - lo) / cell).astype(int), 0, shape)
        covered[tuple(slice(a, b) for a, b in zip(first, end))] = True
    return float(covered.sum() * cell ** len(lo))


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("campaign") / "c"
    summary = run(config_mod.load(lead_follow_toml()), out, resume=False)
    return out, summary


def test_the_hash_of_a_real_campaign_is_the_recorded_formula_and_the_summary_s(campaign):
    out, summary = campaign
    table = pq.read_table(out / "safe_set.parquet")
    centres = np.column_stack([table.column(n).to_numpy() for n in LeadFollow.state_names])
    (width,) = set(table.column("half_width").to_pylist())
    safe_set = SafeSet.from_parquet(out / "safe_set.parquet", LeadFollow.state_names)
    assert len(safe_set) == summary.boxes > 100 and safe_set.is_uniform
    assert safe_set.result_hash == recorded_hash(centres, width) == summary.result_hash
    assert safe_set.volume_union((LeadFollow.lower, LeadFollow.upper)) == summary.volume_union
    # order-independent: the file's rows reversed, or shuffled, hash the same
    shuffled = np.random.default_rng(0).permutation(len(centres))
    assert SafeSet.uniform(centres[shuffled], width, LeadFollow.state_names).result_hash == summary.result_hash
    assert np.array_equal(SafeSet.uniform(centres[shuffled], width, LeadFollow.state_names).sorted().centres,
                          centres)  # the file holds the set sorted


def test_a_mixed_set_hashes_order_independently_and_never_as_a_uniform_one():
    rng = np.random.default_rng(1)
    s = mixed_set(rng)
    order = rng.permutation(len(s))
    assert SafeSet(s.centres[order], s.half_widths[order], NAMES).result_hash == s.result_hash
    widths = s.half_widths.copy()
    widths[0] = 2.0 if widths[0] != 2.0 else 0.5
    assert SafeSet(s.centres, widths, NAMES).result_hash != s.result_hash  # the widths count
    uniform = SafeSet.uniform(s.centres, 0.5, NAMES)
    assert uniform.result_hash == recorded_hash(s.centres, 0.5) != s.result_hash
    assert np.array_equal(s.sorted().centres, s.centres[np.lexsort((s.half_widths, *s.centres.T[::-1]))])


@pytest.mark.parametrize("aligned", [True, False])
@pytest.mark.parametrize("n", [1, 2, 3])
def test_mixed_union_volume_equals_a_raster_count(n, aligned):
    rng = np.random.default_rng(10 * n + aligned)
    s = mixed_set(rng, n=n, boxes=60, aligned=aligned)
    lo, hi = np.full(n, -1.0), np.full(n, 21.0)
    assert s.volume_union() == pytest.approx(raster_volume(s, lo, hi), rel=1e-12)
    # clipped to bounds that cut boxes of every size
    blo, bhi = np.full(n, 1.125), np.full(n, 7.5)
    assert s.volume_union((blo, bhi)) == pytest.approx(raster_volume(s, blo, bhi), rel=1e-12)


def test_mixed_union_volume_with_widths_that_do_not_divide_each_other():
    rng = np.random.default_rng(7)
    centres = rng.integers(0, 64, (50, 2)) / 8.0
    widths = rng.choice([0.375, 0.25, 0.625], 50)
    s = SafeSet(centres, widths, NAMES[:2])
    assert s.volume_union() == pytest.approx(raster_volume(s, [-1, -1], [9, 9]), rel=1e-12)


def test_mixed_hull_volume_is_the_hull_of_every_box_corner():
    rng = np.random.default_rng(3)
    s = mixed_set(rng, boxes=40, aligned=False)
    unit = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    corners = (s.centres[:, None, :] + s.half_widths[:, None, None] * unit).reshape(-1, 3)
    assert s.volume_hull() == pytest.approx(ConvexHull(corners).volume, rel=1e-12)


@pytest.mark.xfail(strict=True, reason="known before SafeSet, left as it was (results must not change): clipped "
                                       "to bounds, only boxes centred on the hull of their size or clipped give "
                                       "corners, yet an unclipped box inside can stick out of the clipped hull "
                                       "(the README main job: 26151.6 against 26157.8)")
def test_hull_volume_clipped_to_bounds_is_the_hull_of_every_clipped_box_corner():
    # four boxes centred on the faces of [0, 10]^2, clipped to half boxes; a box at (2.5,
    # 7.4) inside their diamond sticks out of the clipped ones' hull (its corner (1.5,
    # 8.4) lies above the edge y = x + 6); and a small box in the middle
    centres = np.array([[0.0, 5.0], [10.0, 5.0], [5.0, 10.0], [5.0, 0.0], [2.5, 7.4], [5.0, 5.0]])
    s = SafeSet(centres, np.r_[np.ones(5), 0.5], NAMES[:2])
    bounds = (np.zeros(2), np.full(2, 10.0))
    unit = np.array(list(itertools.product((-1.0, 1.0), repeat=2)))
    corners = np.clip((s.centres[:, None, :] + s.half_widths[:, None, None] * unit).reshape(-1, 2), *bounds)
    assert s.volume_hull(bounds) == pytest.approx(ConvexHull(corners).volume, rel=1e-12)


@pytest.mark.parametrize("n, boxes", [(3, 200), (7, 4000)])
def test_contains_is_membership_in_some_box_of_its_own_size(n, boxes):
    # in 7-D, 20,000 points are asked of a KD-tree per half-width (the volume estimates' way)
    rng = np.random.default_rng(4)
    s = mixed_set(rng, n=n, boxes=boxes, aligned=False)
    points = rng.uniform(-1, 11, (20_000, n))
    corners = s.centres[:200] + s.half_widths[:200, None] * rng.choice([-1.0, 1.0], (200, n))
    points[:200] = corners  # on corners: closed
    points[200:400] = corners + np.sign(corners - s.centres[:200]) * 5e-10  # within the tolerance: inside
    near = rng.integers(0, boxes, 4000)  # around boxes: in and out across their faces
    points[400:4400] = s.centres[near] + s.half_widths[near, None] * rng.uniform(-1.3, 1.3, (4000, n))
    brute = np.concatenate([(np.abs(block[:, None, :] - s.centres[None]) <= s.half_widths[None, :, None] + 1e-9)
                            .all(axis=2).any(axis=1) for block in np.array_split(points, 20)])
    assert np.array_equal(s.contains(points), brute) and brute[:400].all() and 0.05 < brute.mean() < 0.95
    assert ("_trees" in s.__dict__) == (n == 7)
    with pytest.raises(SafeSetError, match=f"states need {n} columns"):
        s.contains(np.zeros((2, 2)))


def test_parquet_round_trip_of_a_mixed_set_with_its_metadata(tmp_path):
    s = mixed_set(np.random.default_rng(5))
    s.to_parquet(tmp_path / "s.parquet", {"config_hash": "abc", "side": "lead"})
    table = pq.read_table(tmp_path / "s.parquet")
    assert table.column_names == [*NAMES, "half_width", *(f"half_width_{a}" for a in NAMES)]  # the public columns
    back = SafeSet.from_parquet(tmp_path / "s.parquet", NAMES)
    assert np.array_equal(back.centres, s.centres) and np.array_equal(back.half_widths, s.half_widths)
    assert back.result_hash == s.result_hash and not back.is_uniform
    assert back.metadata["config_hash"] == "abc" and back.metadata["side"] == "lead"
    assert "scenario_farm_version" in back.metadata
    assert (back.finest, back.coarsest, back.describe_widths()) == (0.25, 1.0, "half-widths 0.25 to 1")
    with pytest.raises(SafeSetError, match="3 different half-widths"):
        back.half_width


@pytest.mark.parametrize("case,message", [
    ("missing", "no such safe-set file"),
    ("not parquet", "not a readable Parquet safe set"),
    ("lacks a column", "lacks column\\(s\\) z"),
    ("another scenario", "has column\\(s\\) w that are not state variables"),
    ("text", "columns must be numbers"),
    ("nan", "non-finite centre or a half_width <= 0; allowed half_width > 0"),
    ("zero width", "non-finite centre or a half_width <= 0; allowed half_width > 0"),
])
def test_a_bad_safe_set_file_is_a_one_line_error_naming_the_file(tmp_path, case, message):
    path = tmp_path / "s.parquet"
    columns = {"x": [1.0, 2.0], "y": [1.0, 2.0], "z": [1.0, 2.0], "half_width": [0.5, 0.25]}
    if case == "not parquet":
        path.write_text("x,y,z\n")
    elif case != "missing":
        if case == "lacks a column":
            del columns["z"]
        elif case == "another scenario":
            columns["w"] = [0.0, 0.0]
        elif case == "text":
            columns["x"] = ["a", "b"]
        elif case == "nan":
            columns["y"] = [np.nan, 1.0]
        elif case == "zero width":
            columns["half_width"] = [0.5, 0.0]
        pq.write_table(pa.table(columns), path)
    with pytest.raises(SafeSetError, match=message) as err:
        SafeSet.from_parquet(path, NAMES)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_a_validation_domain_of_mixed_sizes_samples_uniformly_over_its_union():
    # one box of half-width 2 and eight of 0.5 apart from it: the big one holds 16 of the
    # union's 24 (4 x 4 against 8 x 1 x 1), so 2/3 of uniform samples, not 1/9
    big = np.array([[3.0, 3.0]])
    small = np.array([[x, y] for x in (6.5, 7.5) for y in (0.5, 1.5, 2.5, 3.5)])
    s = SafeSet(np.vstack([big, small]), np.r_[2.0, np.full(8, 0.5)], Toy.state_names)
    domain = Domain.of_set(Toy(), s)
    assert domain.volume() == pytest.approx(16 + 8) and "half-widths 0.5 to 2" in domain.describe()
    points = domain.sample(RunStreams.of(0, np.arange(40_000, dtype=np.uint64)))
    assert s.contains(points).all()
    in_big = (np.abs(points - big[0]) <= 2.0).all(axis=1).mean()
    assert in_big == pytest.approx(16 / 24, abs=0.01)
    # a set of mixed sizes is its own covering down to its finest boxes (boundary
    # refinement exports such sets): Phi_delta holds each box at max(its half-width, delta)
    with pytest.raises(ValueError, match="below the set's smallest box half-width 0.5"):
        domain.lattice(0.25)
    assert len(domain.lattice(0.5)) == len(domain.lattice(2.0)) == 9
    assert np.array_equal(domain.covering(1.0).half_widths, np.r_[2.0, np.full(8, 1.0)])
    assert domain.covering(0.5).volume_union() == pytest.approx(24)


def test_a_uniform_validation_domain_samples_as_before():
    # the rule every recorded validation used: box floor(u * M), then the point in it
    rng = np.random.default_rng(6)
    centres = rng.integers(0, 10, (30, 2)) + 0.5
    s = SafeSet.uniform(centres, 0.5, Toy.state_names)
    streams = RunStreams.of(3, np.arange(2000, dtype=np.uint64))
    points = Domain.of_set(Toy(), s).sample(streams)
    from scenarios.streams import PURPOSE_START

    u = streams.uniform(0, PURPOSE_START, 4)
    first = centres[np.minimum((u[:, 0] * 30).astype(np.int64), 29)] + 0.5 * (2 * u[:, 1:3] - 1)
    accepted = u[:, 3] * np.maximum(1, (np.abs(first[:, None] - centres[None]) <= 0.5 + 1e-12).all(2).sum(1)) <= 1
    assert np.array_equal(points[accepted], np.clip(first[accepted], Toy.lower, Toy.upper))


@pytest.mark.parametrize("n", [9, 10])
def test_membership_works_past_eight_axes(n):
    # the cell hash had multipliers for 8 axes: a 9-D band set failed in its holdout
    rng = np.random.default_rng(n)
    centres = rng.integers(0, 6, size=(500, n)) * 2.0 + 1.0
    widths = np.where(rng.random(500) < 0.5, 1.0, 0.5)
    s = SafeSet(centres, widths, tuple(f"x{i}" for i in range(n)))
    inside = centres + rng.uniform(-0.4, 0.4, size=centres.shape)
    assert s.contains(inside).all()
    far = np.full((3, n), -50.0)
    assert not s.contains(far).any()
