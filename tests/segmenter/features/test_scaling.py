"""Per-channel scaling learned on training data and stored with the class models."""

import numpy as np
import pytest

from handflow.plugins.segmenter import train_class_models
from handflow.plugins.segmenter.features import ChannelScaling
from handflow.plugins.segmenter.models import UKRCandidate, candidate_set, load_candidates, save_class_models


def test_scaling_standardises_and_refuses_bad_input():
    rng = np.random.default_rng(0)
    seqs = [rng.normal([5.0, 0.0], [10.0, 0.1], size=(50, 2)) for _ in range(3)]
    s = ChannelScaling().fit(seqs)
    Z = s.transform(np.vstack(seqs))
    assert np.allclose(Z.mean(axis=0), 0.0, atol=1e-12) and np.allclose(Z.std(axis=0), 1.0)
    with pytest.raises(ValueError, match="channels"):
        s.transform(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="positive scale"):
        ChannelScaling.fitted([0.0, 0.0], [1.0, 0.0])


def test_scaling_survives_save_and_load(synthetic, tmp_path):
    models = train_class_models(synthetic, n_steps=20, random_state=0)
    stored = ChannelScaling.from_model(next(iter(models.values())))
    train = np.vstack([t.data for t in synthetic.train])
    assert np.allclose(stored.offset_, train.mean(axis=0)) and np.allclose(stored.scale_, train.std(axis=0))
    save_class_models(models, tmp_path)
    loaded = load_candidates(tmp_path)
    for m in loaded.models.values():
        assert stored.same_as(m.scaling)
    Y = synthetic.test[0].data
    before, after = candidate_set(models).project(Y), loaded.project(Y)
    assert np.allclose(before.errors, after.errors) and np.allclose(before.latent_time, after.latent_time)


def test_unscaled_models_project_raw_channels(synthetic):
    (model,) = train_class_models(synthetic.restrict(["A"]), n_steps=10, scaling="none").values()
    cand = UKRCandidate(model)
    assert cand.scaling is None
    Y = synthetic.test[0].data
    assert np.array_equal(cand.scaled(Y), Y)
