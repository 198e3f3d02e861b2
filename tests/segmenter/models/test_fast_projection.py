import numpy as np

from handflow.plugins.segmenter.models import BatchedPeriodicProjector, CandidateSet


def test_batched_projection_matches_per_model_transform(candidates, synthetic):
    Y = np.vstack([t.data for t in synthetic.test])
    batched = candidates.project(Y)
    assert candidates._batched_projector() is not None
    per_model = np.column_stack([m.project(Y)[1] for m in candidates.models.values()])
    # never clearly worse than the per-model Levenberg–Marquardt projection
    assert np.mean(batched.errors <= per_model * 1.01 + 1e-9) > 0.98
    lt = np.column_stack([m.project(Y)[0] for m in candidates.models.values()])
    gap = np.abs(np.angle(np.exp(2j * (batched.latent_time - lt)))) / 2
    assert np.median(gap) < 1e-3


def test_batched_projection_of_one_point_equals_batch(candidates, synthetic):
    Y = synthetic.test[0].data[:20]
    whole = candidates.project(Y)
    single = [candidates.project(y[None]) for y in Y]
    np.testing.assert_allclose(np.vstack([s.errors for s in single]), whole.errors, rtol=1e-9, atol=1e-12)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    lat = [np.sort(rng.uniform(0, np.pi, n)) for n in (30, 45)]
    proj = BatchedPeriodicProjector(lat, [rng.normal(size=(len(x), 3)) for x in lat], [8.0, 12.0])
    x = rng.uniform(0, np.pi, (5, 2))
    _, J = proj._f(x, jacobian=True)
    h = 1e-6
    fd = (proj._f(x + h)[0] - proj._f(x - h)[0]) / (2 * h)
    np.testing.assert_allclose(J, fd, rtol=1e-5, atol=1e-7)


def test_mixed_candidate_sets_fall_back_to_per_model_projection(candidates):
    class Constant:
        def project(self, Y):
            return np.zeros(len(Y)), np.ones(len(Y))

    mixed = CandidateSet(dict(candidates.models, const=Constant()))
    proj = mixed.project(np.zeros((3, candidates.models["A"].model.n_features_in_)))
    assert mixed._batched_projector() is None
    np.testing.assert_array_equal(proj.errors[:, -1], 1.0)
