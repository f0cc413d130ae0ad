"""`scenario-farm export DIR --xosc`: a campaign's failing runs and certified set as
ASAM OpenSCENARIO files in DIR/openscenario/.

From a quantification (DIR/recordings/*.mcap, safe_set.parquet):

    road.xodr               the straight road (OpenDRIVE 1.5)
    run-<index>.xosc        each recorded failing run (OpenSCENARIO 1.0)
    logical_scenario.xosc   the scenario whose parameters are the state variables (1.2)
    safe_set.xosc           the certified set over those parameters (1.2 distribution)

From a validation (certificate.json): ``counterexample-<index>.xosc`` for a
counterexample, or, for a certified box domain, ``certified_domain.xosc`` (uniform on
the box) with the logical scenario; a certified set (``domain_set``) as ``safe_set.xosc``.

A scenario with cars that no action column commands (platoon's traffic cars, which drive
an IDM: ``traffic_roles``) gets its recorded runs only, every car replaying its speeds: a
logical scenario holds the actions from t = 0 and has no way to state a car-following model.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from coordinator.domain import Domain
from coordinator.safe_set import SafeSet
from farm.directory.recording import read_recording
from farm.openscenario.ranges import validate_section
from farm.openscenario.distribution import uniform_box, value_sets
from farm.openscenario.elements import write_xml
from farm.openscenario.layout import layout_of
from farm.openscenario.road import write_road
from farm.reports.certificate import FILE as CERTIFICATE_FILE, Certificate
from farm.directory.files import read_json
from farm.openscenario.scenario import concrete_scenario, logical_scenario
from farm.directory.storage import CampaignDir, CampaignError
from farm.reports.summary import Summary
from scenarios.base import EXTERNAL_SV
from scenarios.errors import ConfigError, DataError
from scenarios.registry import backend_class, make_scenario, scenario_options

SUBDIR = "openscenario"
ROAD, LOGICAL = "road.xodr", "logical_scenario.xosc"
MAX_VALUE_SETS = 250_000  # a value set per box: beyond this the file is hundreds of MB


def export_openscenario(directory, *, force: bool = False) -> dict:
    """Write DIR/openscenario/ (see the module docstring); -> {"directory", "files",
    "runs", "notes"}. A non-empty DIR/openscenario/ is refused unless ``force`` (then
    the files of this export are replaced; others there are left alone); a symlink there
    is always refused."""
    directory = Path(directory)
    kind = CampaignDir(directory).open().get("kind")
    cfg = CampaignDir(directory).frozen_config()
    scenario, sv_policy = _scenario(cfg)
    layout = layout_of(scenario)
    notes: list[str] = []
    if kind == "quantify":
        horizon = cfg.quantify.horizon
        summary = Summary.read(directory).to_json()  # checked as every reader of summary.json checks it
        runs = _recorded_runs(directory, scenario, sv_policy, notes)
    elif kind == "validate":
        horizon = cfg.validate.horizon
        path = directory / CERTIFICATE_FILE
        summary = Certificate.from_json(read_json(path, missing=f"{directory}: the validation wrote no certificate "
                                                                f"(no {CERTIFICATE_FILE})"), str(path)).to_json()
        runs = _counterexample(summary)
    else:
        raise CampaignError(f"{directory}: a {kind} directory; export reads quantification and validation directories")
    out = directory / SUBDIR
    if out.is_symlink():  # its target is not ours: --force must not write over a user's files there
        raise CampaignError(f"{out}: a symlink (to {os.readlink(out)}); export writes only into a directory it makes: "
                            f"remove the link or export elsewhere")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise CampaignError(f"{out}: exists and is not empty; pass --force to replace the files export writes there")
    if out.exists() and not out.is_dir():
        raise CampaignError(f"{out}: exists and is not a directory")
    traffic = scenario.traffic_roles
    if traffic:  # a logical scenario holds the actions from t = 0: it cannot say how those cars drive
        notes.append(f"no logical scenario or certified set: {scenario.name}'s traffic model drives "
                     f"{', '.join(traffic)}, which OpenSCENARIO cannot state; the recorded runs replay every "
                     f"vehicle's speeds")
        dist = None
    else:
        dist = _certified(directory, kind, cfg, scenario, summary, notes)  # before any file: a bad set writes none
    out.mkdir(exist_ok=True)
    files = [write_road(out / ROAD, layout.road_length(horizon))]
    for name, trajectory, description in runs:
        files.append(write_xml(out / name, concrete_scenario(layout, trajectory, horizon=horizon,
                                                              description=description, road_file=ROAD,
                                                              sv_policy=sv_policy)))
    if dist is not None:
        file_name, root = dist
        constant = cfg.actions.mode == "constant"
        actions = np.asarray(cfg.actions.value if constant else scenario.adversarial_actions[0],
                             dtype=float).reshape(-1)
        held = ", ".join(f"{scenario.action_words.get(a, a)} {u:g} {scenario.action_units.get(a, '')}".strip()
                         for a, u in zip(scenario.action_names, actions))
        description = (f"scenario-farm {scenario.name} / {sv_policy}: logical scenario; parameters "
                       f"{', '.join(scenario.state_names)} are the start state; held from t = 0: {held} "
                       f"({'the configured constant action' if constant else 'Gamma*, the worst case'})")
        defaults = (scenario.lower + scenario.upper) / 2
        files.append(write_xml(out / LOGICAL, logical_scenario(layout, horizon=horizon, description=description,
                                                               road_file=ROAD, sv_policy=sv_policy,
                                                               defaults=defaults, actions=actions)))
        files.append(write_xml(out / file_name, root))
    return {"directory": str(out), "files": [str(f) for f in files], "runs": len(runs), "notes": notes}


def describe(result: dict) -> str:
    """The CLI's lines for an export."""
    names = [Path(f).name for f in result["files"]]
    lines = [f"{result['directory']}: {result['runs']} scenario(s) of failing runs, {len(names)} files",
             *(f"  {n}" for n in names), *(f"  note: {n}" for n in result["notes"])]
    return "\n".join(lines)


# -- sources ----------------------------------------------------------------------------------
def _scenario(cfg):
    """The scenario object of a frozen config, without starting its back end (SUMO)."""
    sc = cfg.scenario
    external = getattr(backend_class(sc.backend), "external_sv", None)
    scenario = make_scenario(sc.name, EXTERNAL_SV if external else sc.sv_policy, sc.failure_facets, sc.disturbance,
                             scenario_options(sc.model_dump()))
    return scenario, external or scenario.sv_policy_name


def _recorded_runs(directory: Path, scenario, sv_policy: str, notes: list) -> list[tuple[str, np.ndarray, str]]:
    """A damaged recording is left out with a note: it must not hide the others."""
    runs = []
    traffic_note = (f"; {', '.join(scenario.traffic_roles)}: the recorded speeds too (in the farm the traffic IDM "
                    f"drives them after the car ahead: a follower right behind the SV would react to an SV that "
                    f"drives otherwise)") if scenario.traffic_roles else ""
    for path in sorted((directory / "recordings").glob("*.mcap")):
        try:
            rec = read_recording(path)
        except DataError as exc:
            notes.append(f"skipped {exc}")
            continue
        meta = rec["metadata"]
        for index, run in sorted(rec["runs"].items()):
            traj = run["trajectory"]
            description = (f"scenario-farm {scenario.name} / {sv_policy}: a recorded {run['outcome']}, sample {index} "
                           f"of {directory.name} (stream key seed={meta.get('seed')}, index={index}; {len(traj) - 1} "
                           f"steps of {scenario.dt:g} s; config {meta.get('config_hash')}); sv is the controller "
                           f"under test")
            description += traffic_note
            runs.append((f"run-{index}.xosc", traj, description))
    return runs


def _counterexample(cert: dict) -> list[tuple[str, np.ndarray, str]]:
    ce = cert.get("counterexample")
    if not ce:
        return []
    description = (f"scenario-farm {cert.get('scenario')} / {cert.get('sv_policy')}: validation counterexample, "
                   f"sample {ce['sample_index']} (stream key seed={cert.get('seed')}, index={ce['sample_index']}): "
                   f"{ce.get('reason')}; sv is the controller under test")
    return [(f"counterexample-{ce['sample_index']}.xosc", np.asarray(ce["trajectory"], dtype=float), description)]


def _certified(directory: Path, kind: str, cfg, scenario, summary: dict, notes: list):
    """(file name, distribution root) of the certified set, or None (with a note)."""
    names = list(scenario.state_names)
    props = {k: summary[k] for k in ("result_hash", "config_hash", "guarantee") if summary.get(k)}
    if kind == "quantify":
        centres, h = _boxes(directory / "safe_set.parquet", names)
        path_text = "safe_set.parquet"
    else:
        if summary.get("verdict") != "certified":
            return None
        v = cfg.validate
        if v.domain_set:
            try:
                centres, h = _boxes(v.domain_set, names)
            except DataError as exc:
                notes.append(f"the certified set is not exported: {exc}")
                return None
            path_text = v.domain_set
        elif v.constraints or v.domain_predicate:
            notes.append("the certified domain is not exported: its linear constraints or predicate have no "
                         "OpenSCENARIO distribution (only boxes and sets of boxes do)")
            return None
        else:
            try:
                dom = Domain.from_config(scenario, validate_section(v, scenario))
            except ConfigError as exc:
                notes.append(f"the certified domain is not exported: {exc}")
                return None
            description = (f"scenario-farm: the domain certified in {directory.name}, uniform on the box "
                           f"{dom.describe()} (as validate sampled it)")
            props["n_run"] = summary.get("n_run")
            return "certified_domain.xosc", uniform_box(names, dom.lo, dom.hi, scenario_file=LOGICAL,
                                                        description=description, runs=summary.get("n_run") or 1,
                                                        seed=cfg.farm.seed, properties=props)
    if len(centres) > MAX_VALUE_SETS:
        notes.append(f"the certified set is not exported: {len(centres):,} boxes exceed {MAX_VALUE_SETS:,} value sets")
        return None
    if len(centres) == 0:
        notes.append("the certified set is empty: no distribution written")
        return None
    props.update(boxes=len(centres), half_width=h)
    description = (f"scenario-farm: the certified safe set of {directory.name} ({path_text}): {len(centres)} boxes, "
                   f"each its centre (a value set here) +- {h:g} in every state variable")
    return "safe_set.xosc", value_sets(names, centres, scenario_file=LOGICAL, description=description,
                                       properties=props)


def _boxes(path, names) -> tuple[np.ndarray, float]:
    """A safe set's centres and its (finest) half-width."""
    safe_set = SafeSet.from_parquet(path, names)
    return safe_set.centres, safe_set.finest
