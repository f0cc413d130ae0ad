"""A quantification campaign in a directory: start, checkpoint, resume, finish.

The coordinator state (algorithm + driver) is checkpointed every ``checkpoint_every``
seconds at a batch boundary, together with the draws in flight, so a resumed campaign
re-simulates exactly the batches it had drawn and reaches the very result an
uninterrupted run reaches.
"""

from __future__ import annotations

import json
import shutil
import signal
import time
from pathlib import Path

import numpy as np

from coordinator.baselines import make_algorithm
from coordinator.campaign import Campaign, Counters
from coordinator.covering import n_eps
from coordinator.results import result_hash
from farm.files import write_json, write_safe_set
from coordinator.spe import SPESettings
from coordinator.volume import hull_volume, union_volume
from farm import __version__, config as config_mod
from farm.executors import SimSpec, build_simulator
from farm.progress import Progress
from farm.ray_executor import make_executor
from farm.storage import CampaignError, Ledger, load_checkpoint, save_checkpoint, write_status


def settings_of(q: dict) -> SPESettings:
    return SPESettings(delta0=q["delta0"], gamma=q["gamma"], delta_min=q["delta_min"],
                       prioritized=q["prioritized"], alpha=q["alpha"], replay=q["replay"],
                       replay_capacity=q["replay_capacity"], reachable=q["reachable"], boundary=q["boundary"])


def spec_of(cfg: dict, failure_facets=None) -> SimSpec:
    scenario = dict(cfg["scenario"])
    if failure_facets is not None:
        scenario["failure_facets"] = failure_facets
    return SimSpec(scenario, dict(cfg["actions"]), cfg["quantify"]["horizon"], cfg["farm"]["seed"])


def prepare_directory(out: Path, config_path: Path, cfg: dict, *, resume: bool, force: bool) -> bool:
    """-> True if resuming. Refuses a non-empty DIR unless told --resume or --force."""
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        if resume:
            return True
        if not force:
            raise CampaignError(f"{out}: directory is not empty; pass --resume to continue the campaign in it "
                                f"or --force to replace it")
        if not (out / "config.json").exists() and not (out / "checkpoint.npz").exists():
            raise CampaignError(f"{out}: not a campaign directory; refusing to delete it with --force")
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.toml").write_text(Path(config_path).read_text())
    write_json(out / "config.json", {"config": cfg, "config_hash": config_mod.config_hash(cfg),
                                     "scenario_farm_version": __version__})
    return False


def load_frozen_config(out: Path) -> dict:
    try:
        return json.loads((Path(out) / "config.json").read_text())["config"]
    except FileNotFoundError:
        raise CampaignError(f"{out}: not a campaign directory (no config.json)") from None
    except (ValueError, KeyError) as exc:
        raise CampaignError(f"{out}/config.json: unreadable ({exc})") from None


def check_resume_config(out: Path, cfg: dict) -> None:
    frozen = load_frozen_config(out)
    changed = config_mod.changed_fields(frozen, cfg)
    if changed:
        raise CampaignError(f"{out}: the config differs from the campaign's frozen config in {', '.join(changed)}; "
                            f"only farm.workers, farm.executor and farm.address may change on resume")


class Part:
    """One SPE (or baseline) campaign over one set of failure facets, in ``directory``."""

    def __init__(self, cfg: dict, directory: Path, failure_facets=None, label: str = "total"):
        self.cfg, self.dir, self.label = cfg, Path(directory), label
        self.spec = spec_of(cfg, failure_facets)
        self.scenario, self.policy = build_simulator(self.spec)
        q = cfg["quantify"]
        self.n_eps = n_eps(q["epsilon"], q["beta"])
        self.algorithm = make_algorithm(q["algorithm"], self.scenario, settings_of(q), cfg["farm"]["seed"])
        self.ledger = Ledger(self.dir / "ledger", self.scenario.state_names)
        self.config_hash = config_mod.config_hash(cfg)

    def checkpoint(self, campaign: Campaign) -> None:
        self.ledger.append(campaign.log.take())
        if campaign.recordings:
            from farm.recording import write_recording

            rec_dir = self.dir / "recordings"
            rec_dir.mkdir(exist_ok=True)
            # named by the ledger segment they go with (just written), so that resume can drop
            # recordings of a checkpoint that never completed
            write_recording(rec_dir / f"runs-{self.ledger.segments - 1:06d}.mcap", scenario_name=self.scenario.name,
                            state_names=list(self.scenario.state_names), dt=self.scenario.dt,
                            runs=campaign.recordings,
                            metadata={"config_hash": self.config_hash, "seed": str(self.cfg["farm"]["seed"]),
                                      "part": self.label, "scenario_farm_version": __version__})
            campaign.recordings = []
        arrays = {f"algo.{k}": v for k, v in self.algorithm.state().items()}
        arrays.update(campaign.pending_state())
        meta = {"config_hash": self.config_hash, "algorithm": self.algorithm.name, "part": self.label,
                "counters": campaign.counters.__dict__, "final_distribution": campaign.final_distribution,
                "ledger_segments": self.ledger.segments, "ledger_rows": self.ledger.rows}
        save_checkpoint(self.dir / "checkpoint.npz", arrays, meta)

    def restore(self, campaign: Campaign) -> None:
        arrays, meta = load_checkpoint(self.dir / "checkpoint.npz")
        if meta.get("config_hash") != self.config_hash:
            raise CampaignError(f"{self.dir}/checkpoint.npz: stamped with config hash {meta.get('config_hash')}, "
                                f"the config hashes to {self.config_hash}; nothing was changed")
        self.ledger.verify_and_trim(meta["ledger_segments"], meta["ledger_rows"])
        self.algorithm.load_state({k[5:]: v for k, v in arrays.items() if k.startswith("algo.")})
        campaign.load_pending(arrays)
        campaign.counters = Counters(**meta["counters"])
        campaign.final_distribution = meta.get("final_distribution", "")

    def run(self, executor_kind: str, workers: int, address: str, resume: bool, progress: Progress) -> Campaign:
        farm = self.cfg["farm"]
        self.dir.mkdir(parents=True, exist_ok=True)
        executor = make_executor(executor_kind, self.spec, workers, address, farm["max_retries"])
        last = [time.monotonic()]

        def on_batch(c: Campaign) -> None:
            progress.update(self.label, self.algorithm, c, self.n_eps)
            if c.counters.done or time.monotonic() - last[0] >= farm["checkpoint_every"]:
                self.checkpoint(c)
                write_status(self.dir, {"state": "done" if c.counters.done else "running", "part": self.label,
                                        **progress.snapshot(self.algorithm, c, self.n_eps)})
                last[0] = time.monotonic()

        campaign = Campaign(self.algorithm, executor, n_eps=self.n_eps, budget=self.cfg["quantify"]["budget"],
                            batch_size=farm["batch_size"], pipeline_depth=farm["pipeline_depth"],
                            seed=farm["seed"], on_batch=on_batch,
                            record_limit=self.cfg["record"]["quantify_runs"])
        if resume and (self.dir / "checkpoint.npz").exists():
            self.restore(campaign)
        elif resume and any((self.dir / "ledger").glob("segment-*.parquet")):
            raise CampaignError(f"{self.dir}: ledger segments exist but checkpoint.npz is missing; refusing to "
                                f"restart the campaign from scratch over them")
        previous = signal.getsignal(signal.SIGTERM)
        signal.signal(signal.SIGTERM, lambda *_: campaign.stop())
        try:
            if not campaign.counters.done:
                campaign.run()
        except KeyboardInterrupt:
            campaign.stop()
        finally:
            signal.signal(signal.SIGTERM, previous)
            executor.close()
        if not campaign.counters.done:  # stopped: keep what was committed
            self.checkpoint(campaign)
            write_status(self.dir, {"state": "stopped", "part": self.label,
                                    **progress.snapshot(self.algorithm, campaign, self.n_eps)})
            raise KeyboardInterrupt
        return campaign


def guarantee_sentence(cfg: dict, campaign: Campaign, n_eps_value: int, policy_description: str,
                       delta: float) -> str:
    q, c = cfg["quantify"], campaign.counters
    if not c.converged:
        return (f"No guarantee: the budget of {q['budget']} runs was used up before a round at delta = "
                f"{q['delta_min']:g} saw N_eps = {n_eps_value} consecutive runs that changed nothing.")
    gamma = "Gamma*" if cfg["actions"]["mode"] == "adversarial" else "Gamma"
    escaped = c.escaped_in_streak
    core = (f"The last {n_eps_value} committed runs (N_eps = ceil(ln {q['beta']:g} / ln(1 - {q['epsilon']:g}))), "
            f"drawn i.i.d. from the final set ({campaign.final_distribution}; actions {policy_description}), "
            f"neither failed nor found a new state")
    if escaped == 0:
        return (core + f", and none left Phi_delta: the set is ({q['epsilon']:g}, {delta:g})-almost robustly "
                f"controlled forward invariant w.r.t. {gamma} with confidence {1 - q['beta']:g} for that "
                f"sampling distribution.")
    return (core + f"; {escaped} of them left Phi_delta only within delta of a known failure, so the "
            f"{q['epsilon']:g}-almost statement holds for 'no failure and no new state' with confidence "
            f"{1 - q['beta']:g}, not for staying in Phi_delta.")


def finish(cfg: dict, out: Path, parts: dict[str, tuple[Part, Campaign]]) -> dict:
    part, campaign = parts["total"]
    scenario = part.scenario
    centres, h = part.algorithm.result()
    order = np.lexsort(centres.T[::-1])
    centres = centres[order]
    c = campaign.counters
    chash = config_mod.config_hash(cfg)
    rhash = result_hash(centres, h)
    bounds = (scenario.lower, scenario.upper)
    summary = {
        "scenario": cfg["scenario"]["name"],
        "sv_policy": cfg["scenario"]["sv_policy"],
        "backend": cfg["scenario"]["backend"],
        "algorithm": cfg["quantify"]["algorithm"],
        "epsilon": cfg["quantify"]["epsilon"],
        "beta": cfg["quantify"]["beta"],
        "n_eps": part.n_eps,
        "delta_final": h,
        "rounds": c.rounds_completed,
        "converged": c.converged,
        "runs_committed": sum(p[1].counters.committed for p in parts.values()),
        "runs_simulated": sum(p[1].counters.runs_simulated for p in parts.values()),
        "runs_dropped": sum(p[1].counters.runs_dropped for p in parts.values()),
        "steps_simulated": sum(p[1].counters.steps_simulated for p in parts.values()),
        "boxes": int(len(centres)),
        "volume_union": union_volume(centres, h, bounds=bounds),
        "volume_hull": hull_volume(centres, h, bounds=bounds),
        "volume_sigma": scenario.volume,
        "seed": cfg["farm"]["seed"],
        "config_hash": chash,
        "result_hash": rhash,
        "elapsed_s": round(sum(p[1].counters.elapsed_s for p in parts.values()), 3),
        "guarantee": guarantee_sentence(cfg, campaign, part.n_eps, part.policy.description, h),
        "actions": part.policy.description,
        "failure_facets": list(scenario.failure_facets),
        "round_ends": list(c.round_ends),
        "scenario_farm_version": __version__,
    }
    for label, (side_part, side_campaign) in parts.items():
        if label == "total":
            continue
        sc, sh = side_part.algorithm.result()
        summary[f"volume_{label}_side"] = union_volume(sc, sh, bounds=bounds)
        summary[f"volume_hull_{label}_side"] = hull_volume(sc, sh, bounds=bounds)
        summary[f"result_hash_{label}_side"] = result_hash(sc[np.lexsort(sc.T[::-1])], sh)
        summary[f"guarantee_{label}_side"] = guarantee_sentence(cfg, side_campaign, side_part.n_eps,
                                                                side_part.policy.description, sh)
        write_safe_set(out / f"safe_set_{label}_side.parquet", sc, sh, side_part.scenario.state_names,
                       {"config_hash": chash, "side": label})
    write_safe_set(out / "safe_set.parquet", centres, h, scenario.state_names,
                   {"config_hash": chash, "result_hash": rhash})
    write_json(out / "summary.json", summary)
    from farm.plots import draw

    draw(out / "plots", scenario, centres, h, summary)
    for label, (side_part, _) in parts.items():
        if label != "total":
            sc, sh = side_part.algorithm.result()
            draw(out / "plots" / f"{label}_side", side_part.scenario, sc, sh, {**summary, "algorithm": f"{label} side"})
    return summary


def run(cfg: dict, out: Path, *, resume: bool, progress: Progress | None = None) -> dict:
    out = Path(out)
    farm = cfg["farm"]
    progress = progress or Progress(enabled=False)
    parts: dict[str, tuple[Part, Campaign]] = {}
    facet_sets = {"total": cfg["scenario"]["failure_facets"]}
    from scenarios import scenario_class

    declared = scenario_class(cfg["scenario"]["name"]).sides
    sides = cfg["quantify"]["sides"]
    if sides is None:
        sides = bool(declared) and cfg["scenario"]["failure_facets"] is None
    if sides:
        if not declared:
            raise CampaignError(f"quantify.sides: scenario {cfg['scenario']['name']!r} declares no sides")
        facet_sets.update({label: list(facets) for label, facets in declared.items()})
    for label, facets in facet_sets.items():
        directory = out if label == "total" else out / "sides" / label
        part = Part(cfg, directory, facets, label)
        parts[label] = (part, part.run(farm["executor"], farm["workers"], farm["address"], resume, progress))
    progress.close()
    write_status(out, {"state": "finishing"})
    summary = finish(cfg, out, parts)
    write_status(out, {"state": "done", "result_hash": summary["result_hash"]})
    return summary
