"""Run recordings as MCAP files that Foxglove opens without project code.

One topic per scenario, ``/scenario/<name>/state``, JSON-encoded messages with a JSON
schema built from the state names: ``sample_index``, ``step``, ``time`` [s], one number
per state variable, and ``outcome`` on a run's last message (null before). Runs are laid
one after another on the log timeline (each starts 1 s after the previous one ends) so
Foxglove shows them in sequence; the true time within the run is the ``time`` field.
Metadata: a record ``scenario-farm`` (config hash, seed, ...) and one ``run/<index>`` per
run (sample index, outcome, length).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

GAP_NS = 1_000_000_000


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
    from mcap.writer import Writer

    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    topic = f"/scenario/{scenario_name}/state"
    with open(tmp, "wb") as fh:
        writer = Writer(fh)
        writer.start(profile="", library="scenario-farm")
        schema_id = writer.register_schema(name=f"scenario_farm.{scenario_name}.State", encoding="jsonschema",
                                           data=json.dumps(schema_for(scenario_name, state_names)).encode())
        channel_id = writer.register_channel(topic=topic, message_encoding="json", schema_id=schema_id)
        writer.add_metadata("scenario-farm", {k: str(v) for k, v in metadata.items()})
        clock = 0
        step_ns = int(round(dt * 1e9))
        for run in runs:
            traj = np.asarray(run["trajectory"], dtype=float)
            index = int(run["sample_index"])
            for k, state in enumerate(traj):
                msg = {"sample_index": index, "step": k, "time": k * dt}
                msg.update({name: float(v) for name, v in zip(state_names, state)})
                msg["outcome"] = run["outcome"] if k == len(traj) - 1 else None
                stamp = clock + k * step_ns
                writer.add_message(channel_id=channel_id, log_time=stamp, publish_time=stamp, sequence=k,
                                   data=json.dumps(msg).encode())
            clock += len(traj) * step_ns + GAP_NS
            meta = {"sample_index": str(index), "outcome": run["outcome"], "length": str(len(traj))}
            meta.update({k: str(metadata[k]) for k in ("seed", "config_hash") if k in metadata})
            writer.add_metadata(f"run/{index}", meta)
        writer.finish()
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def read_recording(path) -> dict:
    """-> {"metadata", "runs": {index: {"trajectory", "outcome", "metadata"}}, "schema", "topic"}."""
    from mcap.reader import make_reader

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
        raise ValueError(f"{path}: no such recording") from None
    except Exception as exc:  # noqa: BLE001 - the mcap reader raises many kinds on a damaged file
        raise ValueError(f"{path}: not a Scenario Farm recording ({type(exc).__name__}: {exc})") from None
    if "scenario-farm" not in meta or schema is None:
        raise ValueError(f"{path}: not a Scenario Farm recording (no scenario-farm metadata or no messages)")
    runs = {}
    for index, steps in rows.items():
        steps.sort()
        runs[index] = {"trajectory": np.array([s[1] for s in steps]), "outcome": outcomes.get(index),
                       "metadata": meta.get(f"run/{index}", {})}
    return {"metadata": meta["scenario-farm"], "runs": runs, "schema": schema, "topic": topic}
