"""The README's Python example runs as written (from the repository root)."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_readme_python_example_runs_as_written(tmp_path):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python API"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[1] == "[ True False]"
    assert lines[-1].startswith("True With 99% confidence")


def test_the_readme_quotes_the_dimensions_experiment_as_its_json_has_it():
    """The margin refinement's figures in the README are docs/dimensions.json's committed
    runs (they had drifted from a re-run of the experiment)."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    rows = {(r["scenario"], r["delta_min"], r["refine"]): r for r in
            json.loads((root / "docs" / "dimensions.json").read_text())["rows"]}
    readme = " ".join((root / "README.md").read_text().split())
    quoted = {("lead-follow", 0.125, "margin"): "lead-follow idm at delta_min 0.125 in {:,} runs",
              ("lead-follow", 0.125, "band"): "(band: {:,})",
              ("platoon4", 0.5, "margin"): "the 7-D platoon (k = 4) at delta_min 0.5 in {:,} runs",
              ("platoon5", 1.0, "margin"): "the 9-D one (k = 5) at delta_min 1 in {:,},"}
    for key, text in quoted.items():
        assert text.format(rows[key]["runs"]) in readme, f"README: {text.format(rows[key]['runs'])!r} not found"
