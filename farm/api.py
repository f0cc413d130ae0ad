"""The Python API: everything the CLI does, as documented functions.

    from farm import quantify, validate, compare, open_campaign

    result = quantify("examples/lead_follow_idm.toml", out="runs/lf-idm")
    result.volume_union, result.guarantee           # figures and the guarantee
    result.contains([[10.0, 10.0, 40.0]])           # is this state in the safe set?
    cert = validate({"scenario": {"name": "lead-follow", "sv_policy": "brake"},
                     "validate": {"domain_set": "runs/lf-idm/safe_set.parquet"}})
    cert.certified, cert.guarantee, cert.statement  # plain words, the paper's terms

A config is a path to a TOML file, a TOML string, a dict or a ``farm.config.Config``.
What these functions write is a normal campaign directory: every CLI command accepts it.
"""

from __future__ import annotations

import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from farm import config as config_mod
from farm.config import Config
from coordinator.safe_set import SafeSet
from farm.certificate import Certificate, certificate_of
from farm.files import write_json
from farm.storage import CampaignDir, CampaignError
from farm.summary import Summary
from scenarios.errors import DataError


def load_config(source, **overrides) -> Config:
    """A checked config from a TOML path or string, a dict or a Config; keyword
    overrides name fields as ``section__key`` (``farm__workers=4``)."""
    cfg = config_mod.load(source)
    if overrides:
        cfg = cfg.with_overrides({k.replace("__", "."): v for k, v in overrides.items()})
    return cfg


# -- quantification -----------------------------------------------------------------------
@dataclass(frozen=True)
class QuantifyResult:
    """A finished quantification: its safe set (a ``SafeSet``: a union of boxes centre
    +- half-width), its summary (summary.json as a ``Summary``), and the campaign
    directory that holds it all."""

    directory: Path
    summary: Summary
    safe_set: SafeSet

    @classmethod
    def load(cls, directory, side: str | None = None) -> "QuantifyResult":
        directory = Path(directory)
        CampaignDir(directory).open("quantify")
        summary = Summary.read(directory)
        from scenarios.registry import scenario_state_names

        cfg = CampaignDir(directory).frozen_config()
        names = scenario_state_names(cfg.scenario.model_dump())  # a platoon's depend on its k
        path = directory / (f"safe_set_{side}_side.parquet" if side else "safe_set.parquet")
        return cls(directory, summary, SafeSet.from_parquet(path, names))

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.safe_set.state_names

    @property
    def centres(self) -> np.ndarray:
        """(M, n) box centres."""
        return self.safe_set.centres

    @property
    def half_width(self) -> float:
        """The boxes' half-width (``safe_set.half_widths``: one per box, when sizes mix)."""
        return self.safe_set.half_width

    @property
    def guarantee(self) -> str:
        """The guarantee in plain words (summary.json ``guarantee``)."""
        return self.summary.guarantee

    @property
    def guarantee_formal(self) -> str:
        """The same in the paper's terms (summary.json ``guarantee_formal``)."""
        return self.summary.guarantee_formal

    @property
    def volume_union(self) -> float:
        return self.summary.volume_union

    @property
    def volume_hull(self) -> float:
        return self.summary.volume_hull

    @property
    def result_hash(self) -> str:
        return self.summary.result_hash

    def contains(self, states) -> np.ndarray:
        """(B, n) states -> (B,) bool: inside the quantified safe set (l-inf boxes)."""
        return self.safe_set.contains(states)

    def table(self):
        """The safe set as a pyarrow Table (the columns of safe_set.parquet)."""
        return self.safe_set.to_table(self.safe_set.metadata)

    def export_graph(self, path=None) -> Path:
        """The SPE exploration graph as GraphML (networkx): one node per vertex ever
        created, with its state, ``alive`` and ``root`` attributes; an edge from each run's
        start vertex to the states it discovered. Default: DIR/exploration_graph.graphml."""
        import networkx as nx

        from farm.journal import Journal

        state, _ = Journal(self.directory).read(["algo.graph.parent", "algo.vertices.points", "algo.vertices.alive"])
        if "algo.graph.parent" not in state:
            raise CampaignError(f"{self.directory}: algorithm {self.summary.algorithm!r} keeps no "
                                f"exploration graph (only spe does)")
        parent = state["algo.graph.parent"]
        points, alive = state["algo.vertices.points"], state["algo.vertices.alive"].astype(bool)
        graph = nx.DiGraph(scenario=self.summary.scenario, delta=self.safe_set.finest)
        for v in range(len(parent)):
            graph.add_node(int(v), alive=bool(alive[v]),
                           **{name: float(points[v, i]) for i, name in enumerate(self.state_names)})
        child = np.flatnonzero(parent >= 0)
        graph.add_edges_from(zip(parent[child].tolist(), child.tolist()))
        path = Path(path) if path is not None else self.directory / "exploration_graph.graphml"
        nx.write_graphml(graph, path)
        return path

    def report_html(self, path=None) -> Path:
        """One self-contained HTML page: guarantee, figures, rounds, summary (DIR/report.html)."""
        from farm.report import write_html

        return write_html(self.directory, path)

    def plot_failures(self, path=None) -> Path | None:
        """The recorded failing runs over the safe set (DIR/plots/failures.png); None if
        the campaign recorded none."""
        from farm.plots import draw_failures
        from farm.recording import read_recording

        runs = []
        for rec in sorted((self.directory / "recordings").glob("runs-*.mcap")):
            try:
                runs += [r["trajectory"] for r in read_recording(rec)["runs"].values()]
            except DataError as exc:  # a damaged recording must not hide the others (as in replay)
                warnings.warn(f"skipped {exc}", stacklevel=2)
        if not runs:
            return None
        return draw_failures(Path(path) if path else self.directory / "plots" / "failures.png", self._scenario(),
                             self.safe_set, runs[:64])

    def _scenario(self):
        from farm.campaign_setup import spec_of
        from scenarios.registry import make_backend

        return make_backend(spec_of(CampaignDir(self.directory).frozen_config()).scenario).scenario

    def plot(self, out_dir=None) -> list[Path]:
        """Redraw the figures (into DIR/plots by default); -> the files written."""
        from farm.plots import draw
        from farm.campaign_setup import spec_of
        from scenarios.registry import make_backend

        cfg = CampaignDir(self.directory).frozen_config()
        scenario = make_backend(spec_of(cfg).scenario).scenario
        return draw(Path(out_dir) if out_dir else self.directory / "plots", scenario, self.safe_set, self.summary)


def quantify(config, out=None, *, resume: bool = False, force: bool = False, progress: bool = False,
             **overrides) -> QuantifyResult:
    """Find the maximal safe set of ``config`` (a quantification campaign) in directory
    ``out`` (default: a new temporary directory). ``resume`` continues a stopped
    campaign in ``out``; ``force`` replaces a campaign directory there. Keyword
    overrides as in ``load_config`` (``farm__executor="ray"``)."""
    from farm.progress import Progress
    from farm.quantification import run

    text = config_mod.read_text(config) if isinstance(config, (str, Path)) and _is_file(config) else None
    cfg = load_config(config_mod.parse(text, str(config)) if text is not None else config, **overrides)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="scenario-farm-")) / "campaign"
    run(cfg, out, resume=resume, force=force, progress=Progress(enabled=progress), config_text=text)
    return QuantifyResult.load(out)


def plan(config, out=None, *, workers=(1, 32, 256), force: bool = False, run_time: float | None = None,
         call_cost: float | None = None, jitter: float | None = None, progress: bool = False, **overrides) -> dict:
    """Plan a cluster: run ``config`` on the virtual farm (the real coordinator on a
    simulated clock) at each count of ``workers``, in directory ``out`` (default: a new
    temporary directory; ``force`` replaces a plan directory there), each count a normal
    quantify campaign in ``out/workers-<W>``. ``run_time``, ``call_cost`` and ``jitter``
    override ``[farm.virtual]``. Returns the plan (``plan.json``): per count the simulated
    time to the result, the speed-up over the fewest workers, the workers' utilisation,
    the runs and the result hash; and ``recommended_workers``, the fewest within 10 % of
    the fastest. ``plan.png`` draws the time against the workers."""
    from farm.planning import plan as run_plan
    from farm.progress import Progress

    cfg = load_config(config, **overrides)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="scenario-farm-")) / "plan"
    return run_plan(cfg, out, workers, force=force, run_time=run_time, call_cost=call_cost, jitter=jitter,
                    progress=Progress(enabled=progress))


def open_campaign(directory) -> QuantifyResult:
    """The result of a finished campaign directory."""
    return QuantifyResult.load(directory)


def _is_file(source) -> bool:
    try:
        return Path(source).is_file()
    except (OSError, ValueError):
        return False


# -- validation ------------------------------------------------------------------------------
def validate(config, *, out=None, force: bool = False, progress=None, **overrides) -> Certificate:
    """Certify the domain of ``config``'s [validate] section or find the first
    counterexample; with ``out``, write certificate.json (and counterexample.mcap)."""
    from coordinator.domain import Domain
    from coordinator.guarantee import validated
    from coordinator.validation import plan, validate as run_validation
    from farm.simulators import build_simulator
    from farm.executors import make_executor
    from farm.resources import check_validate
    from scenarios.simulator import SimSpec

    cfg = load_config(config, **overrides)
    v, farm_cfg = cfg.validate, cfg.farm
    spec = SimSpec(cfg.scenario.model_dump(), cfg.actions.model_dump(), v.horizon, farm_cfg.seed)
    simulator = build_simulator(spec)
    scenario, policy = simulator.scenario, simulator.policy
    from farm.openscenario.ranges import validate_section

    safe_set = SafeSet.from_parquet(v.domain_set, scenario.state_names) if v.domain_set else None
    domain = Domain.from_config(scenario, validate_section(v, scenario), safe_set)
    check_validate(cfg, domain.lo, domain.hi, domain.is_set)
    p = plan(domain, v.algorithm, v.epsilon, v.beta, v.delta, v.boundary, simulator.deterministic)
    directory = CampaignDir(out) if out is not None else None
    if directory is not None:  # before the runs: a bad --out must not cost a validation
        directory.check_writable()
        marker = directory.marker()
        if marker is None and directory.path.is_dir() and any(directory.path.iterdir()):
            raise CampaignError(f"{out}: not empty and not a directory this tool wrote; choose another --out")
        if marker is not None and marker.get("kind") != "validate":
            raise CampaignError(f"{out}: a {marker.get('kind')} directory; choose another --out")
        if (Path(out) / "certificate.json").exists() and not force:
            raise CampaignError(f"{out}/certificate.json exists; pass --force to replace it")
    executor = make_executor(farm_cfg, spec, check_step_bound=v.boundary)
    try:
        result = run_validation(domain, p, executor, seed=farm_cfg.seed, delta=v.delta, batch_size=farm_cfg.batch_size,
                                pipeline_depth=farm_cfg.pipeline_depth, progress=progress)
    finally:
        executor.close()
    g = validated(scenario, policy, result, algorithm=p.algorithm, plan_description=p.description,
                  epsilon=v.epsilon, beta=v.beta, delta=v.delta, horizon=v.horizon, seed=farm_cfg.seed,
                  adversarial=cfg.actions.mode == "adversarial", mixed=domain.covering(v.delta) is not None)
    cert = certificate_of(cfg, p, result, g, scenario, policy, domain)
    if directory is not None:
        if directory.path.exists() and directory.marker() is not None:
            directory.open("validate")
            directory.lock()
        else:
            directory.create("validate", force=force)
        try:
            write_json(directory.path / "config.json", {"config": cfg.model_dump(mode="json"),
                                                        "config_hash": cert.config_hash})
            cert.write(directory.path)
            if cert.counterexample and cfg.record.counterexamples:
                from farm.rerun import record_counterexample

                record_counterexample(directory.path / "counterexample.mcap", scenario, cert)
        finally:
            directory.unlock()
    return cert


# -- comparison -------------------------------------------------------------------------------
def overlay(results, path) -> Path:
    """Two or more campaigns of one scenario on the same slices (like the paper's Fig. 2:
    brake against idm); ``results``: directories or QuantifyResults."""
    from farm.plots import draw_overlay

    results = [r if isinstance(r, QuantifyResult) else open_campaign(r) for r in results]
    names = {r.summary.scenario for r in results}
    if len(names) != 1:
        raise CampaignError(f"overlay: the campaigns quantify different scenarios ({', '.join(sorted(names))})")
    labels = [f"{r.summary.sv_policy} / {r.summary.actions} ({r.directory.name})" for r in results]
    return draw_overlay(Path(path), results[0]._scenario(), [r.safe_set for r in results], labels)


def compare(target, *, grid: int | None = None, grid_total: int | None = None, estimate_only: bool = False,
            progress=None) -> dict:
    """A finished campaign (directory or QuantifyResult) against the reference safe set:
    IoU, precision, recall, Hausdorff; writes compare.json and plots/compare.png. The
    reference grid: ``grid`` points per axis or ``grid_total`` points in all (default
    ~1.5e6 for a model reference, 24^3 for one simulated with a black-box back end).
    ``progress`` (a farm.progress.Progress) is told the runs it will take and the time
    estimated from a first batch before the rest; ``estimate_only`` returns that plan
    ({"reference_runs", "figure_runs", "estimated_s", ...}) and writes nothing."""
    from farm.compare import compare as run_compare

    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    return run_compare(directory, grid=grid, grid_total=grid_total, estimate_only=estimate_only, progress=progress)


def export_openscenario(target, *, force: bool = False) -> dict:
    """A campaign's failing runs and certified set as ASAM OpenSCENARIO files in
    DIR/openscenario/ (farm/openscenario/export.py): each recorded failing run or
    validation counterexample as a concrete scenario (``run-<index>.xosc``,
    ``counterexample-<index>.xosc``, OpenSCENARIO 1.0) on ``road.xodr`` (OpenDRIVE 1.5),
    and the certified set as a ParameterValueDistribution (``safe_set.xosc`` or
    ``certified_domain.xosc``, 1.2) over ``logical_scenario.xosc``. Returns
    {"directory", "files", "runs", "notes"}; ``force`` replaces an earlier export."""
    from farm.openscenario.export import export_openscenario as run_export

    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    return run_export(directory, force=force)


def falsify(target, *, gamma_star=None, points: int = 10_000, tries: int = 4, seed: int | None = None,
            progress=None) -> dict:
    """Try a worst case Gamma* on the black box (farm/falsify.py): ``gamma_star`` (m
    numbers; default: the proposal in the campaign's adversary.json) held from uniform
    start states; random sequences from Gamma from every start that survives it. Returns
    the report written to falsify.json (``refuted``, ``counterexamples`` with stream keys)."""
    from farm.falsify import falsify as run_falsify

    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    return run_falsify(directory, gamma_star=gamma_star, points=points, tries=tries, seed=seed, progress=progress)
