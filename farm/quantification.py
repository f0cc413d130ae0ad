"""A quantification campaign in a directory: check, start, checkpoint, stop, resume, finish.

The coordinator state (algorithm + driver) is checkpointed every ``farm.checkpoint_every``
seconds at a chunk boundary, together with the draws not yet committed, so a resumed
campaign re-simulates exactly what it had drawn and reaches the very result an
uninterrupted run reaches. SIGINT and SIGTERM stop the campaign at the next chunk
boundary with a checkpoint (a second SIGINT aborts at once; the last checkpoint stands).
"""

from __future__ import annotations

import json
import signal
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from coordinator.adversary import AdversarySearch
from coordinator.baselines import make_algorithm
from coordinator.campaign import Campaign, Counters
from coordinator.sample_size import n_eps, n_eps_attempt
from coordinator.results import result_hash
from coordinator.volume import hull_volume, union_volume
from farm import config as config_mod
from farm.config import Config
from farm.executors import build_simulator
from farm.files import write_json, write_safe_set
from farm.journal import Journal
from farm.memory import release_freed_memory
from farm.progress import Progress
from farm.ray_executor import make_executor
from farm.status import StatusWriter
from farm.resources import check_quantify
from farm.storage import CampaignDir, CampaignError, Ledger
from scenarios.search import SearchActions
from scenarios.simulator import SimSpec
from scenarios.version import __version__


class Stopped(Exception):
    """The campaign was stopped by a signal; it is checkpointed and can be resumed."""


def spec_of(cfg: Config, failure_facets=None) -> SimSpec:
    scenario = cfg.scenario.model_dump()
    if failure_facets is not None:
        scenario["failure_facets"] = list(failure_facets)
    return SimSpec(scenario, cfg.actions.model_dump(), cfg.quantify.horizon, cfg.farm.seed)


def part_facets(cfg: Config, scenario) -> dict[str, list | None]:
    """The sub-campaigns: "total" (the configured failure facets) and, for a scenario
    that declares sides (fleet3: lead, rear), one per side."""
    facets = {"total": cfg.scenario.failure_facets}
    sides = cfg.quantify.sides
    if sides is None:
        sides = bool(scenario.sides) and cfg.scenario.failure_facets is None
    if sides:
        if not scenario.sides:
            raise config_mod.ConfigError(f"quantify.sides: scenario {scenario.name!r} declares no sides; allowed: false")
        facets.update({label: list(side) for label, side in scenario.sides.items()})
    return facets


def load_frozen_config(out: Path) -> Config:
    path = Path(out) / "config.json"
    try:
        raw = json.loads(path.read_text())["config"]
    except FileNotFoundError:
        raise CampaignError(f"{out}: not a campaign directory (no config.json)") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise CampaignError(f"{path}: unreadable ({type(exc).__name__}: {exc})") from None
    try:
        return config_mod.normalize(raw)
    except config_mod.ConfigError as exc:
        raise CampaignError(f"{path}: not a valid frozen config ({exc})") from None


@dataclass
class Part:
    """One SPE (or baseline) campaign over one set of failure facets, in ``directory``."""

    cfg: Config
    directory: Path
    failure_facets: list | None
    label: str = "total"
    campaign: Campaign | None = field(default=None, init=False)

    def __post_init__(self):
        self.directory = Path(self.directory)
        self.spec = spec_of(self.cfg, self.failure_facets)
        self.simulator = build_simulator(self.spec)  # checks scenario, back end and actions now
        self.scenario, self.policy = self.simulator.scenario, self.simulator.policy
        q = self.cfg.quantify
        self.n_eps = n_eps(q.epsilon, q.beta)
        self.algorithm = make_algorithm(q.algorithm, self.scenario, q.settings(), self.cfg.farm.seed,
                                        self.simulator.deterministic)
        self.ledger = Ledger(self.directory / "ledger", self.scenario.state_names)
        self.journal = Journal(self.directory)
        self.config_hash = config_mod.config_hash(self.cfg)

    # -- checkpoints -----------------------------------------------------------------------
    def checkpoint(self) -> None:
        release_freed_memory()  # before the state's arrays are gathered and written
        campaign = self.campaign
        self.ledger.append(campaign.log.take())
        if campaign.recordings:
            from farm.recording import write_recording

            rec_dir = self.directory / "recordings"
            rec_dir.mkdir(exist_ok=True)
            # named by the ledger segment they go with (just written), so that resume can drop
            # recordings of a checkpoint that never completed
            write_recording(rec_dir / f"runs-{self.ledger.segments - 1:06d}.mcap", scenario_name=self.scenario.name,
                            state_names=list(self.scenario.state_names), dt=self.scenario.dt,
                            runs=campaign.recordings,
                            metadata={"config_hash": self.config_hash, "seed": str(self.cfg.farm.seed),
                                      "part": self.label, "scenario_farm_version": __version__})
            campaign.recordings = []
        arrays = {f"algo.{k}": v for k, v in self.algorithm.state().items()}
        arrays.update(campaign.pending_state())
        if campaign.adversary is not None:
            arrays.update(campaign.adversary.state())
        meta = {"config_hash": self.config_hash, "algorithm": self.algorithm.name, "part": self.label,
                "counters": campaign.counters.__dict__, "final_distribution": campaign.final_distribution,
                "ledger_digests": self.ledger.digests, "ledger_rows": self.ledger.rows}
        self.journal.save(arrays, {f"algo.{k}" for k in self.algorithm.append_only}, self.algorithm.state_epoch, meta)

    def restore(self) -> None:
        arrays, meta = self.journal.load()
        if meta.get("config_hash") != self.config_hash:
            raise CampaignError(f"{self.journal.main}: stamped with config hash {meta.get('config_hash')}, "
                                f"the config hashes to {self.config_hash}; nothing was changed")
        try:
            self.ledger.verify_and_trim(meta["ledger_digests"], meta["ledger_rows"])
            self.algorithm.load_state({k[5:]: v for k, v in arrays.items() if k.startswith("algo.")})
            self.algorithm.state_epoch = int(meta.get("epoch", 0))
            self.campaign.load_pending(arrays)
            self.campaign.counters = Counters(**meta["counters"])
            if self.campaign.adversary is not None:
                self.campaign.adversary.load_state(arrays)
        except (KeyError, TypeError, ValueError) as exc:
            raise CampaignError(f"{self.journal.main}: checkpoint lacks {exc} (damaged?); nothing was changed") \
                from None
        self.campaign.final_distribution = meta.get("final_distribution", "")

    # -- running ------------------------------------------------------------------------------
    def prepare(self, resume: bool, progress: Progress, status: StatusWriter) -> None:
        self.progress = progress
        """Set up the campaign driver; when resuming, load and check the checkpoint
        (nothing is written here)."""
        cfg, farm = self.cfg, self.cfg.farm
        last = [time.monotonic()]

        seen_updates = [0]

        def on_chunk(c: Campaign) -> None:
            if c.adversary is not None and len(c.adversary.history) > seen_updates[0]:
                seen_updates[0] = len(c.adversary.history)
                side = "" if self.label == "total" else f"{self.label} side: "
                progress.line(f"{side}search: next round samples {c.adversary.policy.description}")
            progress.update(self.label, self.algorithm, c, self.n_eps)
            status.update(self.label, self.algorithm, c, self.n_eps)
            if time.monotonic() - last[0] >= farm.checkpoint_every:
                self.checkpoint()
                last[0] = time.monotonic()

        self.campaign = Campaign(self.algorithm, None, n_eps=self.n_eps, budget=cfg.quantify.budget,
                                 batch_size=farm.batch_size, pipeline_depth=farm.pipeline_depth, seed=farm.seed,
                                 on_batch=on_chunk, record_limit=cfg.record.quantify_runs,
                                 certify=cfg.quantify.certify and cfg.quantify.algorithm == "spe",
                                 certify_quiet=partial(n_eps_attempt, cfg.quantify.epsilon, cfg.quantify.beta),
                                 adversary=AdversarySearch(self.policy, farm.seed)
                                 if isinstance(self.policy, SearchActions) else None)
        if resume and self.journal.exists():
            self.restore()
        elif resume and any((self.directory / "ledger").glob("segment-*.parquet")):
            raise CampaignError(f"{self.directory}: ledger segments exist but checkpoint.npz is missing; refusing "
                                f"to restart the campaign from scratch over them")

    def run(self, status: StatusWriter) -> Campaign:
        if self.campaign.counters.done:
            return self.campaign
        farm = self.cfg.farm
        self.directory.mkdir(parents=True, exist_ok=True)
        # the handlers cover start-up too: a signal while Ray starts (seconds) is taken
        # once it has started, not in the middle of ray.init (which can crash on it)
        with stop_on_signals(self.campaign):
            t0 = time.monotonic()
            executor = make_executor(farm.executor, self.spec, farm.workers, farm.address, farm.max_retries,
                                     check_step_bound=self.cfg.quantify.boundary, pipeline_depth=farm.pipeline_depth)
            self.startup_s = time.monotonic() - t0
            if farm.executor == "ray":
                self.progress.line(f"Ray ({farm.address}) up with {farm.workers} workers in {self.startup_s:.1f} s")
                busy = executor.busy_at_most(farm.batch_size)
                if busy < farm.workers:  # the cut is fixed by result-relevant settings: say so, do not change it
                    self.progress.line(f"note: {farm.batch_size} x {farm.pipeline_depth} runs in flight "
                                       f"(farm.batch_size x farm.pipeline_depth) keep at most {busy} of the "
                                       f"{farm.workers} workers busy; raise them for more (it costs runs: README, "
                                       f"'Many workers', and docs/window.md)")
            self.campaign.executor = executor
            try:
                self.campaign.run()
            finally:
                executor.close()
        if self.campaign.counters.done:
            self.algorithm.stop_committing()  # the last checkpoint is then gathered with less held
        self.checkpoint()
        if not self.campaign.counters.done:
            status.update(self.label, self.algorithm, self.campaign, self.n_eps, state="stopped", force=True)
            raise Stopped(f"stopped at {self.campaign.counters.committed} committed runs")
        self.algorithm.release()
        release_freed_memory()
        return self.campaign


class stop_on_signals:
    """SIGINT / SIGTERM ask the campaign to stop at the next chunk boundary; a second
    SIGINT aborts at once (the last checkpoint stands, like after kill -9)."""

    def __init__(self, campaign: Campaign):
        self.campaign = campaign

    def _handle(self, signum, frame):
        if self.campaign._stop and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.campaign.stop()

    def __enter__(self):
        self.previous = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def __exit__(self, *exc):
        for s, handler in self.previous.items():
            signal.signal(s, handler)
        return False


def guarantee_of(cfg: Config, part: "Part", delta: float):
    """The plain and formal guarantee of a finished campaign part (coordinator/guarantee.py)."""
    from coordinator.guarantee import quantified

    q, campaign, algo = cfg.quantify, part.campaign, part.algorithm
    certified = campaign.certify and getattr(algo, "certifying", False)
    return quantified(part.scenario, part.policy, epsilon=q.epsilon, beta=q.beta, delta=delta, horizon=q.horizon,
                      n_eps=part.n_eps, attempts=campaign.counters.attempts if certified else 0,
                      n_final=campaign.quiet_needed() if certified else part.n_eps,
                      converged=campaign.counters.converged, budget=q.budget,
                      enumerated=certified and algo.enumerates, boxes=algo.vertices.alive_count if hasattr(
                          algo, "vertices") else 0, uniform=certified, distribution=campaign.final_distribution,
                      escaped=campaign.counters.escaped_in_streak, adversarial=cfg.actions.mode == "adversarial")


def finish(cfg: Config, out: Path, parts: dict[str, Part]) -> dict:
    part = parts["total"]
    campaign, scenario = part.campaign, part.scenario
    centres, h = part.algorithm.result()
    centres = centres[np.lexsort(centres.T[::-1])]
    c = campaign.counters
    chash = config_mod.config_hash(cfg)
    rhash = result_hash(centres, h)
    bounds = (scenario.lower, scenario.upper)
    counters = [p.campaign.counters for p in parts.values()]
    summary = {
        "scenario": cfg.scenario.name,
        "sv_policy": scenario.sv_policy_name,
        "backend": cfg.scenario.backend,
        "algorithm": cfg.quantify.algorithm,
        "epsilon": cfg.quantify.epsilon,
        "beta": cfg.quantify.beta,
        "n_eps": part.n_eps,
        # a sampled certification's attempts, and the quiet runs its last one needed
        # (beta split over attempts); 0 and n_eps without certification
        "certification_attempts": c.attempts,
        "n_eps_final": campaign.quiet_needed() if c.attempts and not part.algorithm.enumerates else part.n_eps,
        "delta_final": h,
        "rounds": c.rounds_completed,
        "converged": c.converged,
        "runs_committed": sum(k.committed for k in counters),
        "runs_simulated": sum(k.runs_simulated for k in counters),
        "runs_dropped": sum(k.runs_dropped for k in counters),
        "steps_simulated": sum(k.steps_simulated for k in counters),
        "boxes": int(len(centres)),
        "volume_union": union_volume(centres, h, bounds=bounds),
        "volume_hull": hull_volume(centres, h, bounds=bounds),
        "volume_sigma": scenario.volume,
        "seed": cfg.farm.seed,
        "config_hash": chash,
        "result_hash": rhash,
        "elapsed_s": round(sum(k.elapsed_s for k in counters), 3),
        "startup_s": round(sum(getattr(p, "startup_s", 0.0) for p in parts.values()), 3),
        "guarantee": (g := guarantee_of(cfg, part, h)).plain,
        "guarantee_formal": g.formal,
        "actions": part.policy.description,
        "failure_facets": list(scenario.failure_facets),
        "round_ends": list(c.round_ends),
        "truncations": {f.label: n for (f, _), n in zip(scenario.facets(), c.truncations) if n},
        "scenario_farm_version": __version__,
    }
    for label, side in parts.items():
        if label == "total":
            continue
        sc, sh = side.algorithm.result()
        summary[f"volume_{label}_side"] = union_volume(sc, sh, bounds=bounds)
        summary[f"volume_hull_{label}_side"] = hull_volume(sc, sh, bounds=bounds)
        summary[f"result_hash_{label}_side"] = result_hash(sc, sh)
        gs = guarantee_of(cfg, side, sh)
        summary[f"guarantee_{label}_side"], summary[f"guarantee_formal_{label}_side"] = gs.plain, gs.formal
        write_safe_set(out / f"safe_set_{label}_side.parquet", sc, sh, side.scenario.state_names,
                       {"config_hash": chash, "side": label})
    write_safe_set(out / "safe_set.parquet", centres, h, scenario.state_names,
                   {"config_hash": chash, "result_hash": rhash})
    for label, p in parts.items():
        if p.campaign.adversary is not None:
            name = "adversary.json" if label == "total" else f"adversary_{label}_side.json"
            write_json(out / name, p.campaign.adversary.report(p.scenario))
    write_json(out / "summary.json", summary)
    from farm.plots import draw

    draw(out / "plots", scenario, centres, h, summary)
    for label, side in parts.items():
        if label != "total":
            sc, sh = side.algorithm.result()
            draw(out / "plots" / f"{label}_side", side.scenario, sc, sh, {**summary, "algorithm": f"{label} side"})
    return summary


def run(cfg: Config, out: Path, *, resume: bool = False, force: bool = False, progress: Progress | None = None,
        config_text: str | None = None) -> dict:
    """Run (or continue) the campaign of ``cfg`` in directory ``out``; -> summary.

    Everything is checked before anything is written: the config, the scenario, the back
    end, the actions. ``resume`` continues a stopped or killed campaign (a finished one
    is left untouched and its summary returned); ``force`` replaces a campaign directory."""
    out = Path(out)
    progress = progress or Progress(enabled=False)
    directory = CampaignDir(out)
    directory.check_writable()
    if resume and _nothing_started(out):
        # killed before its first file: "continue" means start (a plain `resume DIR` has no
        # config to start from and still says "not a campaign directory")
        resume, force = False, True
    if resume:
        directory.open("quantify")
        changed = config_mod.changed_fields(load_frozen_config(out), cfg)
        if changed:
            raise CampaignError(f"{out}: the config differs from the campaign's frozen config in "
                                f"{', '.join(changed)}; only farm.workers, farm.executor and farm.address may "
                                f"change on resume")
        finished = _finished_summary(out)
        if finished is not None:
            return finished
    scenario = build_simulator(spec_of(cfg)).scenario
    check_quantify(cfg, scenario.lower, scenario.upper)
    parts = {label: Part(cfg, out if label == "total" else out / "sides" / label, facets, label)
             for label, facets in part_facets(cfg, scenario).items()}  # builds (checks) every part first
    status = StatusWriter(out)
    try:
        if resume:
            directory.lock(announce=False)
            for part in parts.values():  # every checkpoint is checked before anything is written
                part.prepare(resume, progress, status)
            directory.announce()
            directory.remove_stale_temp_files()
        else:
            directory.create("quantify", force=force)
            (out / "config.toml").write_text(config_text if config_text is not None else _toml_of(cfg))
            write_json(out / "config.json", {"config": cfg.model_dump(mode="json"),
                                             "config_hash": config_mod.config_hash(cfg),
                                             "scenario_farm_version": __version__})
            for part in parts.values():
                part.prepare(resume, progress, status)
        for part in parts.values():
            part.run(status)
        progress.close()
        status.write({"state": "finishing"})
        summary = finish(cfg, out, parts)
        status.write({"state": "done", "result_hash": summary["result_hash"]})
        return summary
    finally:
        directory.unlock()


def _nothing_started(out: Path) -> bool:
    """No directory, an empty one, or one of ours killed before its config was frozen."""
    if not out.exists():
        return True
    if not out.is_dir():
        return False
    names = {p.name for p in out.iterdir()} - {".lock"}
    return not names or (CampaignDir(out).marker() is not None and "config.json" not in names
                         and "checkpoint.npz" not in names and "ledger" not in names)


def _finished_summary(out: Path) -> dict | None:
    try:
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return summary if isinstance(summary, dict) and "result_hash" in summary else None


def _toml_of(cfg: Config) -> str:
    """The normalized config as TOML (for a campaign started from Python)."""
    lines = []
    for section, values in cfg.model_dump(mode="json", exclude_none=True).items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in values.items()]
        lines.append("")
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML form for {value!r}")
