import pytest

from handflow.plugins.manifold import StructuredUKR, toy
from tests.manifold.ukr_helpers import CYL_LATENT, RING_LATENT, closed_curves


@pytest.fixture(scope="session")
def ring_model():
    seqs = closed_curves(noise=0.02)
    return StructuredUKR(latent=RING_LATENT, n_steps=150, isomap_neighbors=(10,), random_state=0).fit(seqs), seqs


@pytest.fixture(scope="session")
def cylinder_model():
    train = toy.cylinder(toy.TRAIN_HEIGHTS, noise=0.1, random_state=3)
    return StructuredUKR(latent=CYL_LATENT, n_steps=150, isomap_neighbors=(10,), random_state=0).fit(train), train
