"""SOM grasp manifold: training, topology, associative completion, resume, files (docs/grasping.md)."""

import numpy as np
import pytest

from handflow.plugins.grasp.som import SOM, decay, load_som, save_som


def plane_postures(n=300, d=12, seed=0):
    """Postures on a smooth 2D manifold embedded in d joints."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, (n, 2))
    A = rng.normal(size=(2, d))
    return np.tanh(u @ A), u


@pytest.mark.parametrize("mode", ["online", "batch"])
def test_training_reduces_quantisation_error(mode):
    X, _ = plane_postures()
    noise = np.random.default_rng(5).normal(X.mean(0), 0.3, (64, X.shape[1]))
    for init in ("pca", noise):
        som = SOM(rows=8, cols=8, epochs=30 if mode == "online" else 100, mode=mode, init=init, random_state=0).fit(X)
        assert som.quantization_error(X) == pytest.approx(som.qe_history_[-1])
        assert som.qe_history_[-1] < 0.7 * som.qe_history_[0]


def test_neighbouring_nodes_have_near_postures():
    X, _ = plane_postures()
    som = SOM(rows=10, cols=10, epochs=40, init="random", random_state=1).fit(X)
    h, v = som.neighbour_distances()
    W = som.postures
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, len(W), (2, 2000))
    random_pairs = np.linalg.norm(W[i] - W[j], axis=1).mean()
    assert np.concatenate([h.ravel(), v.ravel()]).mean() < 0.25 * random_pairs
    assert som.topographic_error(X) < 0.2


def test_lattice_keeps_the_latent_order():
    """Nodes far apart on the lattice win data far apart on the manifold (topology preserved)."""
    X, u = plane_postures(n=400)
    som = SOM(rows=10, cols=10, epochs=40, random_state=0).fit(X)
    pos = som.transform(X)
    corr = np.corrcoef(np.linalg.norm(pos[:200] - pos[200:], axis=1), np.linalg.norm(u[:200] - u[200:], axis=1))[0, 1]
    assert corr > 0.7


def test_pcp_best_match_ignores_unspecified_joints():
    nodes = np.array([[0.0, 0.0, 5.0], [1.0, 1.0, 0.0], [0.0, 0.1, -3.0]])
    som = SOM(rows=1, cols=3, epochs=1, init=nodes, lr=(1e-9, 1e-9), sigma=(1e-3, 1e-3)).fit(nodes)
    theta = np.array([0.0, 0.0, 100.0])  # the third joint is wildly off …
    assert som.best_match(theta)[0] == 0  # … and decides the plain match,
    mask = np.array([1, 1, 0])  # but the PCP leaves it out
    assert som.best_match(theta, mask)[0] == 0
    theta2 = np.array([0.0, 0.12, 0.0])
    assert som.best_match(theta2, mask)[0] == 2
    np.testing.assert_allclose(som.complete(theta2, mask)[0], nodes[2])


def test_partial_fit_moves_the_manifold_towards_new_postures():
    X, _ = plane_postures()
    som = SOM(rows=6, cols=6, epochs=20, random_state=0).fit(X)
    new = X[:20] + 0.5
    before = som.quantization_error(new)
    som.partial_fit(new)
    assert som.quantization_error(new) < before
    assert som.n_updates_ == 2
    assert len(som.qe_history_) == 1 + 20 + 10


def test_save_and_load_round_trip(tmp_path):
    X, _ = plane_postures(n=50)
    som = SOM(rows=4, cols=5, epochs=5, random_state=3).fit(X)
    save_som(som, tmp_path / "som.npz", {"names": [f"j{k}" for k in range(X.shape[1])], "object": "box"})
    loaded, meta = load_som(tmp_path / "som.npz")
    np.testing.assert_array_equal(loaded.nodes_, som.nodes_)
    np.testing.assert_array_equal(loaded.best_match(X), som.best_match(X))
    assert meta["object"] == "box" and loaded.get_params() == som.get_params()
    with np.load(tmp_path / "som.npz", allow_pickle=False) as f:  # no pickle anywhere
        assert set(f.files) == {"nodes", "qe_history", "metadata"}


def test_bad_input_is_refused_with_a_clear_message(tmp_path):
    X, _ = plane_postures(n=30)
    with pytest.raises(ValueError, match="NaN"):
        SOM(rows=3, cols=3, epochs=1).fit(np.where(np.eye(30, X.shape[1]) > 0, np.nan, X))
    with pytest.raises(ValueError, match="mode"):
        SOM(mode="magic").fit(X)
    som = SOM(rows=3, cols=3, epochs=1).fit(X)
    with pytest.raises(ValueError, match="joints"):
        som.best_match(X[:, :3])
    with pytest.raises(ValueError, match="no joint"):
        som.best_match(X[0], np.zeros(X.shape[1]))
    np.savez(tmp_path / "other.npz", a=np.zeros(2))
    with pytest.raises(ValueError, match="no grasp SOM metadata.*grasp-som"):
        load_som(tmp_path / "other.npz")


def test_decay_schedules_reach_their_end_values():
    for schedule in ("exponential", "linear"):
        assert decay(0.95, 0.05, 0.0, schedule) == pytest.approx(0.95)
        assert decay(0.95, 0.05, 1.0, schedule) == pytest.approx(0.05)
    assert decay(6, 0.7, 0.5, "exponential") == pytest.approx(np.sqrt(6 * 0.7))
