"""The docs whose tables come from an experiment's JSON are exactly what their renderer
makes of it: an edit by hand, or a JSON re-run without re-rendering, fails here."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RENDERED = {  # renderer -> the docs it writes
    "experiments/convergence.py": ["convergence.md", "convergence_table.md"],
    "experiments/figures.py": ["figures.md"],
    "experiments/adversary.py": ["adversary.md"],
    "experiments/reproduce.py": ["reproduction.md"],
    "experiments/window.py": ["window.md"],
    "experiments/coupling_bound.py": ["coupling_bound.md"],
    "experiments/certification.py": ["certification.md"],
    "experiments/certification_tail.py": ["certification_tail.md"],
    "benchmarks/bench_virtual.py": ["virtual.md"],
    "benchmarks/bench_scaling.py": ["scaling.md"],
    "experiments/refinement.py": ["refinement.md"],
    "experiments/certified_sets.py": ["guarantee.md"],
    "experiments/guarantee_check.py": ["guarantee.md"],
    "experiments/estimate.py": ["estimate.md"],
    "experiments/holdout_check.py": ["guarantee.md"],
    "experiments/dimensions.py": ["dimensions.md"],
}


@pytest.mark.parametrize("script", sorted(RENDERED))
def test_rendered_docs_match_their_json(tmp_path, script):
    # a copy of experiments/, benchmarks/ and docs/: the renderers write next to themselves
    for folder in ("experiments", "benchmarks", "docs"):
        shutil.copytree(ROOT / folder, tmp_path / folder)
    r = subprocess.run([sys.executable, str(tmp_path / script), "--render"], capture_output=True,
                       text=True, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr
    for doc in RENDERED[script]:
        assert (tmp_path / "docs" / doc).read_text() == (ROOT / "docs" / doc).read_text(), (
            f"docs/{doc} differs from `python {script} --render`")
