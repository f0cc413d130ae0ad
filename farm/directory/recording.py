"""Run recordings as MCAP files that Foxglove opens without project code.

One topic per run, ``/scenario/<name>/run/<sample index>``, every run starting at log
time 0: in Foxglove each run is its own series, overlaid on one time axis (a plot of
``/scenario/lead-follow/run/*.v0`` shows every run's v0 from its start; with one topic
laid back to back, runs joined into one line). JSON-encoded messages with a JSON schema
built from the state names: ``sample_index``, ``step``, ``time`` [s], one number per
state variable, and ``outcome`` on a run's last message (null before). Messages are
written in log-time order. Metadata: a record ``scenario-farm`` (config hash, seed, ...)
and one ``run/<index>`` per run (sample index, outcome, length). Beside each recording, a
Foxglove layout (``<name>.layout.json``: one plot per state variable with every run of the
file as a series; Foxglove: Layouts > Import from file).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from mcap.reader import make_reader
from mcap.writer import Writer

from farm.directory.files import atomic_write, write_json
from scenarios.errors import DataError

def schema_for(scenario_name: str, state_names: list[str]) -> dict:
    props = {"sample_index": {"type": "integer"}, "step": {"type": "integer"},
             "time": {"type": "number", "description": "seconds since the run's start"}}
    props.update({name: {"type": "number"} for name in state_names})
    props["outcome"] = {"type": ["string", "null"], "enum": ["failure", "truncated", "horizon", None]}
    return {"title": f"scenario-farm {scenario_name} state", "type": "object", "properties": props,
            "required": ["sample_index", "step", "time", *state_names]}


def write_recording(path, *, scenario_name: str, state_names: list[str], dt: float, runs: list[dict],
                    metadata: dict[str, str]) -> None:
    """Write ``runs`` (dicts with sample_index, trajectory (L, n), outcome) atomically."""
    def write(fh) -> None:
        writer = Writer(fh)
        writer.start(profile="", library="scenario-farm")
        schema_id = writer.register_schema(name=f"scenario_farm.{scenario_name}.State", encoding="jsonschema",
                                           data=json.dumps(schema_for(scenario_name, state_names)).encode())
        writer.add_metadata("scenario-farm", {k: str(v) for k, v in metadata.items()})
        trajs = [np.asarray(run["trajectory"], dtype=float) for run in runs]
        channels = [writer.register_channel(topic=f"/scenario/{scenario_name}/run/{int(run['sample_index'])}",
                                            message_encoding="json", schema_id=schema_id) for run in runs]
        step_ns = int(round(dt * 1e9))
        for k in range(max((len(t) for t in trajs), default=0)):  # log-time order across runs
            for run, traj, channel in zip(runs, trajs, channels):
                if k >= len(traj):
                    continue
                msg = {"sample_index": int(run["sample_index"]), "step": k, "time": k * dt}
                msg.update({name: float(v) for name, v in zip(state_names, traj[k])})
                msg["outcome"] = run["outcome"] if k == len(traj) - 1 else None
                writer.add_message(channel_id=channel, log_time=k * step_ns, publish_time=k * step_ns, sequence=k,
                                   data=json.dumps(msg).encode())
        for run, traj in zip(runs, trajs):
            meta = {"sample_index": str(int(run["sample_index"])), "outcome": run["outcome"], "length": str(len(traj))}
            meta.update({k: str(metadata[k]) for k in ("seed", "config_hash") if k in metadata})
            writer.add_metadata(f"run/{int(run['sample_index'])}", meta)
        writer.finish()

    atomic_write(Path(path), write)
    write_layout(Path(path).with_suffix(".layout.json"), scenario_name, state_names,
                 [int(run["sample_index"]) for run in runs])


def write_layout(path: Path, scenario_name: str, state_names: list[str], indices: list[int]) -> None:
    """A Foxglove layout: a column of plots, one per state variable, a series per run."""
    panels = {}
    for name in state_names:
        panels[f"Plot!{name}"] = {
            "title": name, "showLegend": len(indices) <= 16, "xAxisVal": "timestamp", "isSynced": True,
            "paths": [{"value": f"/scenario/{scenario_name}/run/{i}.{name}", "enabled": True,
                       "timestampMethod": "receiveTime", "label": f"run {i}"} for i in indices]}
    layout: object = f"Plot!{state_names[-1]}"
    for name in reversed(state_names[:-1]):
        layout = {"direction": "column", "first": f"Plot!{name}", "second": layout}
    write_json(path, {"configById": panels, "globalVariables": {}, "userNodes": {}, "linkedGlobalVariables": [],
                      "playbackConfig": {"speed": 1}, "layout": layout})


def read_recording(path) -> dict:
    """-> {"metadata", "runs": {index: {"trajectory", "outcome", "metadata"}}, "schema", "topic"}."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            fh.seek(0)
            reader = make_reader(fh)
            rows: dict[int, list] = {}
            outcomes: dict[int, str] = {}
            schema, topic, names = None, None, None
            for sch, channel, message in reader.iter_messages():
                if schema is None:
                    schema, topic = json.loads(sch.data), channel.topic
                    names = [p for p in schema["properties"] if p not in ("sample_index", "step", "time", "outcome")]
                msg = json.loads(message.data)
                rows.setdefault(msg["sample_index"], []).append((msg["step"], [msg[n] for n in names]))
                if msg.get("outcome"):
                    outcomes[msg["sample_index"]] = msg["outcome"]
    except FileNotFoundError:
        raise DataError(f"{path}: no such recording") from None
    except Exception as exc:  # noqa: BLE001 - the mcap reader raises many kinds on a damaged file
        raise DataError(f"{path}: not a Scenario Farm recording ({type(exc).__name__}: {exc})") from None
    if "scenario-farm" not in meta or schema is None:
        raise DataError(f"{path}: not a Scenario Farm recording (no scenario-farm metadata or no messages)")
    runs = {}
    for index, steps in rows.items():
        steps.sort()
        runs[index] = {"trajectory": np.array([s[1] for s in steps]), "outcome": outcomes.get(index),
                       "metadata": meta.get(f"run/{index}", {})}
    return {"metadata": meta["scenario-farm"], "runs": runs, "schema": schema, "topic": topic}
