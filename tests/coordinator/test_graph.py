"""The exploration forest's reachable() against networkx on random forests, and the
GraphML export of a real campaign's graph."""

import networkx as nx
import numpy as np
import pytest

from coordinator.graph import ExplorationForest
from farm import api


def random_forest(seed: int):
    rng = np.random.default_rng(seed)
    forest, graph = ExplorationForest(), nx.DiGraph()
    for _ in range(60):  # interleaved as SPE does: new roots at round ends, children per run
        if rng.random() < 0.3 or len(forest) == 0:
            k = int(rng.integers(1, 5))
            first = len(forest)
            forest.add_roots(k)
            graph.add_nodes_from(range(first, first + k))
        else:
            parent, k = int(rng.integers(len(forest))), int(rng.integers(1, 4))
            first = len(forest)
            forest.add_children(parent, k)
            graph.add_edges_from((parent, c) for c in range(first, first + k))
    return forest, graph


@pytest.mark.parametrize("seed", range(10))
def test_reachable_matches_networkx(seed):
    forest, graph = random_forest(seed)
    undirected = graph.to_undirected()
    for v in range(len(forest)):
        assert set(forest.reachable(v, "undirected").tolist()) == nx.node_connected_component(undirected, v)
        assert set(forest.reachable(v, "ancestors").tolist()) == nx.ancestors(graph, v) | {v}


def test_report_graph_writes_the_campaign_graph_as_graphml(tmp_path):
    result = api.quantify({"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
                           "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.01, "horizon": 30},
                           "farm": {"executor": "local", "batch_size": 256}}, out=tmp_path / "q")
    graph = nx.read_graphml(result.export_graph())
    alive = [n for n, a in graph.nodes(data=True) if a["alive"]]
    assert len(alive) == result.summary["boxes"]
    assert graph.number_of_edges() > 0 and nx.is_forest(graph)
    alive_points = np.array(sorted((graph.nodes[n]["v0"], graph.nodes[n]["v1"], graph.nodes[n]["p10"]) for n in alive))
    np.testing.assert_array_equal(alive_points, np.array(sorted(map(tuple, result.centres))))
