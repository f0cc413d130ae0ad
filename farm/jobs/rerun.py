"""Re-run a committed run from its stream key and check it against what was recorded.

`scenario-farm replay DIR --sample N`: in a quantification campaign, the ledger row of
sample N (start state, outcome, steps) and, if the run was recorded, its MCAP trajectory;
in a validation directory, the counterexample of certificate.json.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pyarrow.dataset as ds

from coordinator.adversary import schedule_state
from farm.directory.journal import Journal
from farm.directory.recording import read_recording, write_recording
from farm.reports.certificate import FILE as CERTIFICATE_FILE, Certificate
from farm.execution.process import build_simulator
from farm.directory.storage import CampaignDir, read_ledger
from scenarios.base import OUTCOME_NAMES
from scenarios.errors import CampaignError, ConfigError, DataError
from scenarios.simulator import SimSpec


def rerun(simulator, index: int, start: np.ndarray):
    batch = simulator.simulate(index, start[None, :])
    return batch.trajectory(0), OUTCOME_NAMES[int(batch.outcomes[0])]


def record_counterexample(path: Path, scenario, cert: Certificate) -> None:
    ce = cert.counterexample
    write_recording(path, scenario_name=scenario.name, state_names=list(scenario.state_names), dt=scenario.dt,
                    runs=[{"sample_index": ce["sample_index"], "trajectory": np.array(ce["trajectory"]),
                           "outcome": ce["outcome"]}],
                    metadata={"config_hash": cert.config_hash, "seed": str(cert.seed),
                              "kind": "validation counterexample", "reason": ce["reason"],
                              "scenario_farm_version": cert.scenario_farm_version})


def _recorded(directory: Path, index: int):
    """The recording holding run ``index`` (path, run) or (None, None). A damaged file is
    skipped with a warning: it must not hide the runs recorded in the others."""
    for path in sorted((directory / "recordings").glob("*.mcap")) + sorted(directory.glob("*.mcap")):
        try:
            rec = read_recording(path)
        except DataError as exc:
            print(f"scenario-farm: warning: skipped {exc}", file=sys.stderr)
            continue
        if index in rec["runs"]:
            return path, rec["runs"][index]
    return None, None


def _load_adaptive_actions(directory: Path, simulator) -> None:
    """An adaptive action policy (actions.mode = "search") is a function of the run's key
    and the campaign's weight schedule, which the last checkpoint holds."""
    if simulator.policy.state() is None:
        return
    arrays, _ = Journal(directory).read(["adv.firsts", "adv.weights"])
    schedule = schedule_state(arrays)
    if schedule is not None:
        simulator.policy.load(schedule)


def replay(directory: Path, index: int) -> tuple[bool, bool, str]:
    """Re-run sample ``index`` of DIR; -> (whether it matches the record, whether the run
    is a finding: a validation's counterexample, the report's lines)."""

    directory = Path(directory)
    CampaignDir(directory).open()  # a one-line error for a file or a directory not ours
    if (directory / CERTIFICATE_FILE).exists():
        return _replay_counterexample(directory, index)

    cfg = CampaignDir(directory).frozen_config()
    if not 0 <= index < 2**63:
        raise ConfigError(f"--sample: {index} is out of range; allowed [0, 2**63)")
    rows = read_ledger(directory, filter=ds.field("sample_index") == index).to_pylist()
    rows = [r for r in rows if not r.get("discarded")]  # the run used at this index (a replacement, if any)
    if not rows:
        raise CampaignError(f"{directory}: sample {index} is not in the ledger (not committed)")
    row = rows[0]
    spec = SimSpec(cfg.scenario.model_dump(), cfg.actions.model_dump(), cfg.quantify.horizon, cfg.farm.seed)
    simulator = build_simulator(spec)
    _load_adaptive_actions(directory, simulator)
    scenario = simulator.scenario
    start = np.array([row[name] for name in scenario.state_names])
    traj, outcome = rerun(simulator, index, start)
    checks = [("outcome", outcome == row["outcome"], f"{outcome} (ledger: {row['outcome']})"),
              ("steps", len(traj) - 1 == row["steps"], f"{len(traj) - 1} (ledger: {row['steps']})")]
    path, recorded = _recorded(directory, index)
    if recorded is not None:
        same = recorded["trajectory"].shape == traj.shape and np.array_equal(recorded["trajectory"], traj)
        checks.append(("trajectory", same, f"{len(traj)} states, identical to {path.name}" if same else
                       f"differs from {path.name}"))
    ok = all(c[1] for c in checks)
    lines = [f"sample {index} (stream key seed={spec.seed}, index={index}) from "
             f"{dict(zip(scenario.state_names, start.tolist()))}:"]
    lines += [f"  {'ok  ' if good else 'DIFF'} {name}: {text}" for name, good, text in checks]
    lines.append("replay matches the record" if ok else "replay does NOT match the record")
    return ok, False, "\n".join(lines)


def _replay_counterexample(directory: Path, index: int) -> tuple[bool, bool, str]:
    ce = Certificate.read(directory).counterexample
    if not ce or ce["sample_index"] != index:
        raise CampaignError(f"{directory}: certificate.json holds no counterexample with sample index {index}")

    cfg = CampaignDir(directory).frozen_config()
    spec = SimSpec(cfg.scenario.model_dump(), cfg.actions.model_dump(), cfg.validate.horizon, cfg.farm.seed)
    simulator = build_simulator(spec)
    start = np.array([ce["start_state"][name] for name in simulator.scenario.state_names])
    traj, outcome = rerun(simulator, index, start)
    expected = np.array(ce["trajectory"])
    k = ce["violating_step"]
    same = len(traj) > k and np.array_equal(traj[: k + 1], expected)
    checks = [("trajectory", same, f"identical up to the violating step {k}" if same else "differs")]
    path, recorded = _recorded(directory, index)
    if recorded is not None:
        rec_same = np.array_equal(recorded["trajectory"], expected)
        checks.append(("recording", rec_same, f"{path.name} holds the same {len(expected)} states"))
    ok = all(c[1] for c in checks)
    lines = [f"counterexample sample {index} (stream key seed={spec.seed}, index={index}): {ce['reason']}"]
    lines += [f"  {'ok  ' if good else 'DIFF'} {name}: {text}" for name, good, text in checks]
    lines.append("replay reproduces the counterexample" if ok else "replay does NOT reproduce the counterexample")
    return ok, True, "\n".join(lines)
