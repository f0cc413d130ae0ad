"""A finished quantification as one object: its safe set, its summary and its directory,
with the figures, the HTML report and the exploration graph made from them."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from coordinator.safe_set import SafeSet
from farm import lazy
from farm.directory.journal import Journal
from farm.directory.storage import CampaignDir, CampaignError
from farm.execution.process import spec_of
from farm.reports.summary import Summary
from scenarios.errors import DataError
from scenarios.registry import make_backend, scenario_state_names


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
        nx = lazy.networkx
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
        return lazy.html.write_html(self.directory, path)

    def plot_failures(self, path=None) -> Path | None:
        """The recorded failing runs over the safe set (DIR/plots/failures.png); None if
        the campaign recorded none."""
        runs = {}
        for rec in sorted((self.directory / "recordings").glob("runs-*.mcap")):
            try:
                runs.update((index, r["trajectory"]) for index, r in lazy.recording.read_recording(rec)["runs"].items())
            except DataError as exc:  # a damaged recording must not hide the others (as in replay)
                warnings.warn(f"skipped {exc}", stacklevel=2)
        if not runs:
            return None
        shown = sorted(runs)[:64]
        # labelled by sample index, as `scenario-farm replay DIR --sample N` takes them
        return lazy.plots.draw_failures(Path(path) if path else self.directory / "plots" / "failures.png", self._scenario(),
                                        self.safe_set, [runs[i] for i in shown], [f"sample {i}" for i in shown])

    def _scenario(self):
        return make_backend(spec_of(CampaignDir(self.directory).frozen_config()).scenario).scenario

    def plot(self, out_dir=None, hold: dict[str, float] | None = None) -> list[Path]:
        """Redraw the figures (into DIR/plots by default); -> the files written.
        ``hold``: state name -> the value the slices and 3-D views hold that axis at
        (default mid-range); ValueError on an unknown name or a value outside Sigma."""
        return lazy.plots.draw(Path(out_dir) if out_dir else self.directory / "plots", self._scenario(), self.safe_set,
                               self.summary, hold=hold)
