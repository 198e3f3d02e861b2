import pytest

from handflow.plugins.manifold import StructuredUKR
from handflow.plugins.manifold.construction import ManifoldConstruction
from handflow.plugins.manipulation import BALL_NAMES, ManipulationManifold
from tests.manipulation.synthetic import BALL_JOINTS, CAP_NAMES, ball_sequences, cap_sequences


@pytest.fixture(scope="session")
def construction():
    seqs, radii, phases = cap_sequences()
    return ManifoldConstruction(n_steps=60).fit(seqs, radii), seqs, radii, phases


@pytest.fixture(scope="session")
def cap_manifold(construction):
    return ManipulationManifold(construction[0].model_, CAP_NAMES, "shadow", ["time", "radius_cm"], "constructed")


@pytest.fixture(scope="session")
def ball_manifold():
    seqs = ball_sequences()
    model = StructuredUKR(
        latent=[{"kernel": "periodic", "beta": 30, "time": True}],
        lambda_pvar=0.0,
        n_steps=100,
        isomap_neighbors=(10,),
        random_state=0,
    ).fit(seqs)
    return ManipulationManifold(model, BALL_JOINTS + list(BALL_NAMES), "gifu", ["time"], "ball_swap")


@pytest.fixture
def manifold_file(tmp_path):
    """Save a manifold and return its path."""

    def save(manifold, name="m.npz"):
        path = tmp_path / name
        manifold.save(path)
        return path

    return save


@pytest.fixture(scope="session")
def ball_manifold_file():
    """The project's ball-swap manifold (configs/models, built on first use)."""
    from pathlib import Path

    from handflow.plugins.manipulation.cli import ensure_manifold

    return ensure_manifold("balls", Path(__file__).resolve().parents[2] / "configs" / "models", say=lambda line: None)
