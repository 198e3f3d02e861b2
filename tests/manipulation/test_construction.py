"""Manifold by construction (docs/manipulation.md) on synthetic radius-labelled sequences."""

import numpy as np
import pytest

from handflow.plugins.manifold import InvalidInputError
from handflow.plugins.manifold.construction import ManifoldConstruction, monotone_projection
from tests.manipulation.synthetic import cap_sequences


def _phase_spread(latent_times, phases, at=(0.2, 0.4, 0.6, 0.8)):
    """Largest std across sequences of the latent time at the same true phase."""
    q = np.array([np.interp(at, ph, t) for t, ph in zip(latent_times, phases)])
    return q.std(axis=0).max()


def test_sequences_of_one_radius_share_one_latent_radius(construction):
    builder, seqs, radii, _ = construction
    model = builder.model_
    for sid in np.unique(model.sequence_ids_):
        r = model.latents_[model.sequence_ids_ == sid, 1]
        assert np.ptp(r) == 0.0
        assert r[0] == builder.sequence_radius_[sid]
    assert sorted(np.unique(model.latents_[:, 1])) == sorted(set(radii))
    assert [r for r, _ in builder.stages_] == sorted(set(radii))


def test_construction_synchronises_phases_across_sequences(construction):
    builder, seqs, radii, phases = construction
    X, ids = builder.model_.latents_, builder.model_.sequence_ids_
    times = [X[ids == k, 0] for k in range(len(seqs))]
    ordered_phases = [phases[i] for i in builder.sequence_order_]
    span = np.ptp(X[:, 0])
    naive = _phase_spread([np.linspace(0, 1, len(p)) for p in phases], phases)
    synced = _phase_spread(times, ordered_phases) / span
    assert synced < 0.5 * naive


def test_projected_phase_of_the_same_posture_agrees_across_radii(construction):
    builder, seqs, radii, phases = construction
    # the same-phase posture of every radius projected onto its own radius row
    from tests.manipulation.synthetic import posture

    lat = [builder.model_.transform(posture([0.5], r), mask=None)[0] for r in sorted(set(radii))]
    times = np.array([x[0] for x in lat])
    assert np.ptp(times) < 0.1 * np.ptp(builder.model_.latents_[:, 0])


def test_time_axis_is_chronological(construction):
    builder, seqs, _, _ = construction
    X, ids = builder.model_.latents_, builder.model_.sequence_ids_
    for k in range(len(seqs)):
        t = X[ids == k, 0]
        assert np.corrcoef(np.arange(len(t)), t)[0, 1] > 0.95


def test_monotone_projection_is_order_preserving_and_exact_on_the_curve():
    F = np.c_[np.linspace(0, 1, 50), np.linspace(0, 1, 50) ** 2]
    idx = np.array([3, 3, 10, 20, 21, 40])
    assert np.array_equal(monotone_projection(F[idx], F), idx)
    # a closed cycle: start and end postures coincide; pointwise would map the end to the start
    G = np.c_[np.cos(np.linspace(0, 2 * np.pi, 60)), np.sin(np.linspace(0, 2 * np.pi, 60))]
    a = monotone_projection(G[::6], G)
    assert np.all(np.diff(a) >= 0) and a[-1] > 50


def test_bad_input_names_what_to_change():
    seqs, radii, _ = cap_sequences(radii=(1.5, 2.0), per_radius=1)
    with pytest.raises(InvalidInputError, match="one radius per sequence"):
        ManifoldConstruction().fit(seqs, radii[:1])
    with pytest.raises(InvalidInputError, match="synchronisation"):
        ManifoldConstruction(synchronisation="dtw").fit(seqs, radii)
    with pytest.raises(InvalidInputError, match="fewer than 4"):
        ManifoldConstruction().fit([seqs[0], seqs[1][:2]], radii)
