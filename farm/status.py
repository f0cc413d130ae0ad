"""`scenario-farm status DIR`: a campaign's state from its files alone."""

from __future__ import annotations

import json
import time
from pathlib import Path

from farm.storage import pid_alive, read_status


def describe(directory: Path) -> str:
    directory = Path(directory)
    if not (directory / "config.json").exists():
        raise ValueError(f"{directory}: not a campaign directory (no config.json)")
    lines = [f"campaign {directory}"]
    cfg = json.loads((directory / "config.json").read_text())
    c = cfg["config"]
    lines.append(f"  scenario {c['scenario']['name']} / {c['scenario']['sv_policy']} / {c['quantify']['algorithm']}, "
                 f"config hash {cfg['config_hash']}")
    for label, path in [("total", directory)] + [(p.name, p) for p in sorted((directory / "sides").glob("*"))]:
        st = read_status(path)
        if st is None:
            lines.append(f"  [{label}] not started")
            continue
        state = st.get("state", "?")
        age = time.time() - st.get("heartbeat", 0)
        if state == "running" and not pid_alive(int(st.get("pid", -1))):
            state = "stopped (process gone; continue with `scenario-farm resume`)"
        elif state == "running":
            state = f"running (pid {st['pid']}, last checkpoint {age:.0f} s ago)"
        fields = ["round", "delta", "boxes", "n_eps_counter", "n_eps", "runs_committed", "runs_simulated",
                  "runs_per_s", "elapsed_s", "result_hash"]
        detail = ", ".join(f"{k} {st[k]}" for k in fields if st.get(k) is not None)
        lines.append(f"  [{label}] {state}" + (f": {detail}" if detail else ""))
    if (directory / "summary.json").exists():
        s = json.loads((directory / "summary.json").read_text())
        lines.append(f"  finished: {s['boxes']} boxes, volume {s['volume_union']:.6g}, result hash {s['result_hash']}")
        lines.append(f"  {s['guarantee']}")
    return "\n".join(lines)
