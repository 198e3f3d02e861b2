"""A candidate set holds the feature pipeline its models were trained on; model files written
before it was held still load, with the pipeline their provenance records
(plugins/segmenter/features/_pipeline.py, docs/segmentation.md)."""

from pathlib import Path

import numpy as np
import pytest

from handflow.plugins.segmenter.features import DelayEmbedding, Derived, FeaturePipeline, Headings
from handflow.plugins.segmenter.models import CandidateSet, fit_recording_models, load_candidates

SHIPPED = Path(__file__).resolve().parents[3] / "configs" / "models" / "gestures"


def test_shipped_model_files_load_with_the_pipeline_they_record():
    cands = load_candidates(SHIPPED)
    assert isinstance(cands.pipeline, FeaturePipeline)
    assert cands.pipeline == FeaturePipeline.from_provenances(
        [m.model.provenance_ for m in cands.models.values()], cands.scaling
    )
    Y = np.random.default_rng(0).normal(size=(30, cands.n_channels))
    rows, reversed_rows = cands.pipeline.transform_both(Y)
    stream = cands.pipeline.stream()
    pushed = [stream.push(y) for y in Y]
    np.testing.assert_array_equal(np.vstack([r for r, _ in pushed]), rows)
    assert (reversed_rows is None) == (not cands.headings.active)


def test_trained_candidates_hold_the_pipeline_their_files_would_record():
    rng = np.random.default_rng(1)
    t = np.linspace(0, 6 * np.pi, 240)
    by_class = {
        "a": [np.c_[np.sin(t), np.cos(t)] + 0.01 * rng.normal(size=(240, 2))],
        "b": [np.c_[np.sin(2 * t), np.cos(t)] + 0.01 * rng.normal(size=(240, 2))],
    }
    cands = fit_recording_models(
        by_class, delay=4, n_steps=20, random_state=0, derived="velocities", scaling="standard"
    )
    assert (cands.delay, cands.derived, cands.headings) == (DelayEmbedding(4), Derived("velocities"), Headings())
    reread = CandidateSet(cands.models)  # what a saved and loaded set reads from the provenance
    assert reread.pipeline.delay == cands.delay and reread.pipeline.derived == cands.derived
    assert reread.scaling.same_as(cands.scaling)
    Y = np.c_[np.sin(t[:50]), np.cos(t[:50])]
    np.testing.assert_array_equal(reread.project(Y).errors, cands.project(Y).errors)


def test_models_of_different_pipelines_are_refused():
    with pytest.raises(ValueError, match="different delay embeddings"):
        FeaturePipeline.from_provenances([{"delay_window": 2}, {"delay_window": 3}])


def test_the_error_metric_comes_from_at_most_the_capped_frames_per_class():
    """Above ``MAX_STATISTICS_FRAMES`` the models' error statistics come from evenly thinned whole
    segments (docs/segmentation.md, "Class models for real recordings"): the reference is the
    median own-model error of exactly those segments, and the rest of the fit is unchanged."""
    from handflow.plugins.segmenter.models import thin_pieces

    rng = np.random.default_rng(2)
    t = np.linspace(0, 4 * np.pi, 120)
    by_class = {
        "a": [np.c_[np.sin(t + k), np.cos(t + k)] + 0.02 * rng.normal(size=(120, 2)) for k in range(4)],
        "b": [np.c_[np.sin(2 * t + k), np.cos(t)] + 0.02 * rng.normal(size=(120, 2)) for k in range(4)],
    }
    full = fit_recording_models(by_class, delay=4, n_steps=20, random_state=0)
    capped = fit_recording_models(by_class, delay=4, n_steps=20, random_state=0, statistics_frames=250)
    kept = {c: thin_pieces(segs, 250) for c, segs in by_class.items()}
    assert all(len(k) == 2 for k in kept.values())  # the cap binds: half the segments per class
    full_reference = full.models["a"].model.provenance_["error_reference"]
    own = np.concatenate([full.project(s).errors[:, j] for j, c in enumerate(kept) for s in kept[c]])  # relative
    reference = capped.models["a"].model.provenance_["error_reference"]
    assert reference == pytest.approx(float(np.median(own)) * full_reference, rel=1e-9)
    assert reference != full_reference
    for c in by_class:  # the manifolds themselves are fitted on the same points
        np.testing.assert_array_equal(capped.models[c].model.latents_, full.models[c].model.latents_)


def test_class_models_fitted_over_processes_are_those_fitted_one_after_the_other():
    """``jobs=2`` fits the class manifolds in forked workers on one BLAS thread (train-classes on
    recordings): the same latents, provenance and projections as the fits in this process."""
    rng = np.random.default_rng(2)
    t = np.linspace(0, 6 * np.pi, 240)
    by_class = {
        c: [np.c_[np.sin(k * t), np.cos(t), np.sin(t + k)] + 0.01 * rng.normal(size=(240, 3))]
        for c, k in (("a", 1), ("b", 2), ("c", 3))
    }
    alone, pooled = (
        fit_recording_models(by_class, delay=4, n_steps=20, random_state=0, scaling="standard", jobs=jobs)
        for jobs in (1, 2)
    )
    assert list(pooled.models) == ["a", "b", "c"]
    for c in by_class:
        a, b = alone.models[c].model, pooled.models[c].model
        np.testing.assert_array_equal(a.latents_, b.latents_)
        assert a.provenance_ == b.provenance_
    X = np.vstack(by_class["b"])
    np.testing.assert_array_equal(alone.project(X).errors, pooled.project(X).errors)
