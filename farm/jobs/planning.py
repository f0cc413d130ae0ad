"""Plan a cluster before renting it: one campaign on the virtual farm per worker count.

The virtual farm (farm/execution/virtual.py) runs the real coordinator on a simulated
clock, so each campaign's result is the real one and only its time is modelled. ``plan``
runs the same config at every worker count asked, each in a campaign directory of its own
(``workers-<W>/``, a normal quantify directory), and writes what a user compares:
``plan.json`` (time to the result, speed-up, the workers' utilisation, the shares of the
time the coordinator waited for runs and spent on its own CPU, runs, the result hash per
worker count) and ``plan.png`` (time to the result against workers, with the
ideal line). The count to rent is where more workers stop paying: ``plan`` names the
fewest workers within ``NEAR_BEST`` of the fastest time.
"""

from __future__ import annotations

from pathlib import Path

from farm import config as config_mod, lazy
from farm.config import Config
from farm.directory.files import write_json
from farm.reports.progress import Progress
from farm.directory.storage import CampaignDir, CampaignError
from farm.jobs.quantification import run
from scenarios.errors import ConfigError

PLAN_FILE, PLOT_FILE = "plan.json", "plan.png"
NEAR_BEST = 1.1  # the recommended count: the fewest workers within this factor of the fastest time
MAX_COUNTS = 16  # worker counts in one plan (each is a whole campaign)


def virtual_config(cfg: Config, workers: int, run_time: float | None = None, call_cost: float | None = None,
                   jitter: float | None = None) -> Config:
    """``cfg`` on the virtual farm with ``workers`` simulated workers (and, where given,
    its ``[farm.virtual]`` run time, call cost and jitter). A value out of range is a
    ``ConfigError`` naming its flag."""
    raw = cfg.model_dump()
    raw["farm"].update(executor="virtual", workers=workers)
    given = {"run_time": run_time, "call_cost": call_cost, "jitter": jitter}
    raw["farm"]["virtual"].update({k: v for k, v in given.items() if v is not None})
    flags = {"farm.workers": "--workers"} | {f"farm.virtual.{k}": f"--{k.replace('_', '-')}" for k in given}
    return config_mod.normalize(raw, flags=flags)


def plan(cfg: Config, out: Path, workers, *, force: bool = False, run_time: float | None = None,
         call_cost: float | None = None, jitter: float | None = None, progress: Progress | None = None) -> dict:
    """Run ``cfg`` on the virtual farm at each worker count of ``workers`` in directory
    ``out`` (``force`` replaces a plan directory there); -> the plan (also ``plan.json``).

    Every count runs the same campaign (the virtual farm's result does not depend on the
    workers: a plan whose result hashes differ is an error of ours). Speed-ups are over
    the fewest workers asked: ask 1 too for the speed-up over one worker."""
    counts = sorted({int(w) for w in workers})
    if not counts:
        raise ConfigError("--workers: give at least one worker count")
    if len(counts) > MAX_COUNTS:
        raise ConfigError(f"--workers: {len(counts)} counts; allowed at most {MAX_COUNTS} (each is a whole campaign)")
    configs = {w: virtual_config(cfg, w, run_time, call_cost, jitter) for w in counts}  # all checked first
    out = Path(out)
    directory = CampaignDir(out)
    marker = directory.marker() if out.is_dir() else None
    if not force and out.is_dir() and any(out.iterdir()):
        raise CampaignError(f"{out}: directory is not empty; pass --force to replace the plan in it")
    if force and marker is not None and marker.get("kind") != "plan":
        raise CampaignError(f"{out}: a {marker.get('kind')} directory, not a plan; refusing to replace it with --force")
    directory.create("plan", force=force)
    progress = progress or Progress(enabled=False)
    try:
        rows = []
        for i, (w, wcfg) in enumerate(configs.items()):
            progress.line(f"plan: {w:,} virtual workers ({i + 1} of {len(configs)})")
            summary = run(wcfg, out / f"workers-{w}", progress=progress)
            elapsed = summary["virtual_elapsed_s"]
            rows.append({"workers": w, "virtual_elapsed_s": elapsed, "utilisation": summary["utilisation"],
                         "waiting_share": _share(summary["virtual_waiting_s"], elapsed),
                         "coordinator_share": _share(summary["virtual_coordinator_s"], elapsed),
                         "runs_committed": summary["runs_committed"],
                         "runs_simulated": summary["runs_simulated"], "result_hash": summary["result_hash"]})
        result = _plan_of(configs[counts[0]], rows)
        write_json(out / PLAN_FILE, result)
        lazy.plots.draw_plan(out / PLOT_FILE, result, NEAR_BEST)
        return result
    finally:
        directory.unlock()


def _share(seconds: float, elapsed: float) -> float:
    return round(seconds / elapsed, 4) if elapsed else 0.0


def _plan_of(cfg: Config, rows: list[dict]) -> dict:
    base = rows[0]
    for r in rows:
        r["speed_up"] = round(base["virtual_elapsed_s"] / r["virtual_elapsed_s"], 2) if r["virtual_elapsed_s"] else None
    best = min(r["virtual_elapsed_s"] for r in rows)
    recommended = next(r["workers"] for r in rows if r["virtual_elapsed_s"] <= NEAR_BEST * best)
    v = cfg.farm.virtual
    return {"run_time": v.run_time, "call_cost": v.call_cost, "jitter": v.jitter, "speed_up_over": base["workers"],
            "recommended_workers": recommended, "same_result": len({r["result_hash"] for r in rows}) == 1,
            "rows": rows}


def table(result: dict) -> str:
    """The plan as lines of text (what ``scenario-farm plan`` prints)."""
    lines = [f"virtual farm: a full-horizon run {result['run_time']:g} s, a chunk call {result['call_cost']:g} s, "
             f"jitter {result['jitter']:g}",
             f"{'workers':>8} {'time to result':>16} {'speed-up':>9} {'utilisation':>12} {'head waiting':>13} "
             f"{'coordinator':>12} {'runs simulated':>15}"]
    for r in result["rows"]:
        lines.append(f"{r['workers']:>8,} {_duration(r['virtual_elapsed_s']):>16} {r['speed_up']:>8.1f}x "
                     f"{r['utilisation']:>12.2f} {r['waiting_share']:>13.0%} {r['coordinator_share']:>12.0%} "
                     f"{r['runs_simulated']:>15,}")
    base, rows = result["speed_up_over"], result["rows"]
    lines.append(f"speed-up over {base} worker{'s' if base > 1 else ''}; the fewest workers within {NEAR_BEST:g}x "
                 f"of the fastest: {result['recommended_workers']:,}"
                 + (" (the time still falls there: ask for more)"
                    if result["recommended_workers"] == rows[-1]["workers"] and len(rows) > 1 else ""))
    lines.append("head waiting: the share of the time to the result the coordinator waited for runs; "
                 "coordinator: its own CPU (the rest: its chunk calls). Waiting with the workers busy (utilisation "
                 "near 1): more workers help; waiting with workers idle: the campaign's order bounds it (the runs "
                 "a change or a round's end needs first); a large coordinator share: a faster driver would help")
    lines.append("one result at every count: " + ("yes" if result["same_result"] else
                                                    "NO (an error of scenario-farm: please report it)"))
    return "\n".join(lines)


def _duration(seconds: float) -> str:
    if seconds >= 3600:
        return f"{seconds / 3600:.1f} h"
    if seconds >= 60:
        return f"{seconds / 60:.1f} min"
    return f"{seconds:.1f} s"
