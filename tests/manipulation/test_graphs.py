"""The graphs configs/cap_turning.yaml and configs/ball_swap.yaml: controller params resolve and
load the project's manifolds; slow: each graph runs a few seconds with ``handflow run``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.manipulation import nodes
from handflow.plugins.manipulation.cli import ensure_manifold

REPO = Path(__file__).resolve().parents[2]
CONFIGS = REPO / "configs"
NODES = {
    "manipulation.open_loop": "OpenLoopNode",
    "manipulation.feedback_init": "FeedbackInitNode",
    "manipulation.closed_loop": "ClosedLoopNode",
}
GRAPHS = {"cap_turning.yaml": "constructed", "ball_swap.yaml": "balls"}


@pytest.fixture(scope="module")
def project_models():
    """The manifolds the graphs use (cached in configs/models, built on first use)."""
    return {name: ensure_manifold(name, CONFIGS / "models", say=lambda line: None) for name in set(GRAPHS.values())}


def _controller(graph):
    spec = yaml.safe_load((CONFIGS / graph).read_text())
    return next(n for n in spec["nodes"] if n["plugin"] in NODES)


@pytest.mark.parametrize("graph", sorted(GRAPHS))
def test_graph_controller_params_load_the_project_manifold(graph, project_models):
    node = _controller(graph)
    cls = getattr(nodes, NODES[node["plugin"]])
    h = NodeHarness(cls, node["params"], base_dir=CONFIGS).setup()
    assert h.node.manifold.model.n_features_in_ == len(h.node.manifold.names)


@pytest.mark.slow
def test_cap_turning_graph_closes_on_the_cap(tmp_path, run_handflow, project_models):
    rec = tmp_path / "cap.mcap"
    run_handflow("validate", "configs/cap_turning.yaml", check=True)
    run_handflow("run", "configs/cap_turning.yaml", "--duration", "10", "--record", str(rec), check=True, timeout=180)
    latents = [m.coords for t, m, _ in read_messages(rec) if t.endswith("controller/latent")]
    touched = {b for t, m, _ in read_messages(rec) if t.endswith("sim/contacts") for b in m.bodies}
    radii = np.array([x[1] for x in latents])
    assert len(latents) > 50 and radii[0] == pytest.approx(3.5)
    assert np.all(np.diff(radii) <= 1e-12) and radii[-1] < 3.4  # navigating towards the cap
    assert "cap" in touched


@pytest.mark.slow
def test_ball_swap_graph_runs_closed_loop(tmp_path, run_handflow, project_models):
    rec = tmp_path / "balls.mcap"
    run_handflow("validate", "configs/ball_swap.yaml", check=True)
    run_handflow("run", "configs/ball_swap.yaml", "--duration", "10", "--record", str(rec), check=True, timeout=180)
    topics = [t for t, _, _ in read_messages(rec)]
    assert sum(t.endswith("tracker/balls") for t in topics) >= 3  # camera → tracker
    targets = [m for t, m, _ in read_messages(rec) if t.endswith("controller/targets")]
    latents = [m for t, m, _ in read_messages(rec) if t.endswith("controller/latent")]
    assert targets and targets[0].hand == "gifu" and latents  # tracker → controller → sim
