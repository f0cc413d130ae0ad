"""experiments/truth.py, the second copy of the dynamics written from the spec alone,
labels random states as the farm's own model reference does (scenario.reference_safe)."""

import sys
from pathlib import Path

import numpy as np
import pytest

from scenarios.registry import make_scenario
from source_imports import source_imports

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"
sys.path.insert(0, str(EXPERIMENTS))
import truth  # noqa: E402

POINTS = 20_000
# truth case -> the farm's scenario name, SV policy, options, failure facets (None: all)
CASES = {
    "lead-follow/brake": ("lead-follow", "brake", {}, None),
    "lead-follow/idm": ("lead-follow", "idm", {}, None),
    "fleet3/brake": ("fleet3", "brake", {}, None),
    "fleet3/idm": ("fleet3", "idm", {}, None),
    "fleet3/idm/lead": ("fleet3", "idm", {}, ["p10"]),
    "fleet3/brake/rear": ("fleet3", "brake", {}, ["p20"]),
    "platoon4/idm": ("platoon", "idm", {"vehicles": 4}, None),
    "platoon4/brake": ("platoon", "brake", {"vehicles": 4}, None),
    "platoon5/idm": ("platoon", "idm", {"vehicles": 5}, None),
    "platoon5/brake": ("platoon", "brake", {"vehicles": 5}, None),
    "platoon5r2/idm/rear": ("platoon", "idm", {"vehicles": 5, "followers": 2}, ["p30"]),
    "lead-follow-params/idm": ("lead-follow-params", "idm", {}, None),
    "lead-follow-params/brake": ("lead-follow-params", "brake", {}, None),
}


@pytest.mark.parametrize("case", list(CASES))
def test_truth_labels_agree_with_the_farms_reference(case):
    name, policy, options, facets = CASES[case]
    scenario = make_scenario(name, policy, facets, options=options)
    points, safe = truth.truth_points(case, POINTS, seed=1)
    assert points.shape == (POINTS, scenario.n) and safe.dtype == bool
    assert np.all((points >= scenario.lower) & (points <= scenario.upper))
    reference = scenario.reference_safe(points)
    agree = int((safe == reference).sum())
    print(f"{case}: {int(safe.sum())} of {POINTS} safe; truth and farm agree on {agree}")
    assert agree >= 0.9999 * POINTS
    assert 0 < safe.sum() < POINTS  # both labels occur: the comparison is not vacuous


def test_the_same_seed_gives_the_same_points_and_labels():
    a, b = truth.truth_points("platoon4/idm", 2000, seed=5), truth.truth_points("platoon4/idm", 2000, seed=5)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], truth.truth_points("platoon4/idm", 2000, seed=6)[0])


def test_the_truth_copy_is_independent_of_the_farm():
    imported = {name.split(".")[0] for path, _, name in source_imports("experiments") if path.name == "truth.py"}
    assert not imported & {"scenarios", "coordinator", "farm"}, imported


def test_unknown_cases_are_refused():
    with pytest.raises(ValueError, match="is not a case"):
        truth.make_case("platoon4/acc")
