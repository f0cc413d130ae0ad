"""docs/foxglove_layout.json: a Foxglove layout for the recordings of the lead-follow
campaign of the README (examples/lead_follow_idm.toml, seed 0): one plot per state
variable (v0, v1, p10), every recorded run as a series on its own topic.

It is written by ``farm.directory.recording.write_layout``, the function that writes the layout
beside every recording, from the run indices the campaign records (the campaign is
deterministic: same config and seed, same recorded runs), so it cannot drift from what
the tool writes:

    python experiments/foxglove_layout.py                      # runs the campaign in a temp dir (~5 s)
    python experiments/foxglove_layout.py runs/lead-follow-idm  # or takes the runs of a finished one
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "foxglove_layout.json"
CONFIG = ROOT / "examples" / "lead_follow_idm.toml"


def recorded(directory: Path) -> tuple[str, list[str], list[int]]:
    """(scenario name, state names, sample indices) of every run recorded in a campaign."""
    from farm.directory.recording import read_recording

    name, states, indices = None, None, []
    for path in sorted((Path(directory) / "recordings").glob("runs-*.mcap")):
        rec = read_recording(path)
        name = rec["topic"].split("/")[2]
        states = [p for p in rec["schema"]["properties"] if p not in ("sample_index", "step", "time", "outcome")]
        indices += sorted(rec["runs"])
    if not indices:
        raise SystemExit(f"{directory}: no recorded runs")
    return name, states, indices


def main(argv: list[str]) -> Path:
    from farm import quantify
    from farm.directory.recording import write_layout

    if argv:
        directory = Path(argv[0])
    else:
        directory = Path(tempfile.mkdtemp(prefix="foxglove-layout-")) / "lf-idm"
        quantify(CONFIG, out=directory, farm__executor="local")
    name, states, indices = recorded(directory)
    write_layout(OUT, name, states, indices)
    print(f"{OUT}: {len(states)} plots ({', '.join(states)}), {len(indices)} runs of {name}")
    return OUT


if __name__ == "__main__":
    main(sys.argv[1:])
