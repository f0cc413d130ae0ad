"""docs/foxglove_layout.json is what farm.directory.recording.write_layout writes today for the
lead-follow runs it names (regenerate it with `python experiments/foxglove_layout.py`)."""

import json
import re
from pathlib import Path

from farm.directory.recording import write_layout
from scenarios.lead_follow import LeadFollow

LAYOUT = Path(__file__).resolve().parents[2] / "docs" / "foxglove_layout.json"


def test_the_docs_layout_is_the_one_the_recordings_get(tmp_path):
    layout = json.loads(LAYOUT.read_text())
    names = list(LeadFollow("idm").state_names)
    assert list(layout["configById"]) == [f"Plot!{name}" for name in names]  # a plot per state variable
    paths = layout["configById"][f"Plot!{names[0]}"]["paths"]
    indices = [int(re.fullmatch(r"/scenario/lead-follow/run/(\d+)\.v0", p["value"]).group(1)) for p in paths]
    assert len(indices) > 1
    write_layout(tmp_path / "layout.json", "lead-follow", names, indices)
    assert json.loads((tmp_path / "layout.json").read_text()) == layout
