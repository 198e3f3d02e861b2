"""The evaluation's CLM over a scorer maps scores as the online node does (docs/segmentation.md,
"Score sources")."""

from __future__ import annotations

import numpy as np
import pytest

from handflow.plugins.segmenter.compatibility import evidence_temperature
from handflow.plugins.segmenter.datasets import load_recordings
from handflow.plugins.segmenter.evaluation import REGISTRY, RecordingsEvaluator
from handflow.plugins.segmenter.scorers import DTWScorer


def _fitted_on_fold(npz, name: str, params: dict):
    """``name`` fitted on the training recordings of fold r0 (training z-score, no derived
    features): the method, its fit, the training segments and the held-out recording."""
    ev = RecordingsEvaluator(load_recordings(npz), methods=(name,), quick=True)
    train, test = ev.fold_views("r0")["training", "none"]
    segments = ev._segments(train)
    method = REGISTRY[name]
    return method, method.fit(segments, params, 0), segments, test


def test_clm_dtw_maps_scores_to_evidence_at_the_saved_scorers_temperature(three_class_npz):
    method, fitted, segments, test = _fitted_on_fold(three_class_npz, "clm_dtw", {"window": 20})
    assert not hasattr(fitted.model, "temperature_")  # dtw_1nn alone never scores the training frames
    node = DTWScorer(window=20).fit({str(c): segments[c] for c in sorted(segments)})  # what fit-scorer saves
    state = method.prepare(fitted, test.X)
    assert method._temperature(fitted) == pytest.approx(node.temperature_, rel=1e-12)
    assert method._temperature(fitted) != pytest.approx(evidence_temperature(state))  # not the held-out recording's
    np.testing.assert_allclose(method.evidence(fitted, state, None), node.evidence(node.scores(test.X)), atol=1e-12)


def test_clm_minirocket_maps_scores_at_its_scorers_fitted_temperature(three_class_npz):
    pytest.importorskip("aeon")
    method, fitted, _, test = _fitted_on_fold(three_class_npz, "clm_minirocket", {"window": 32})
    state = method.prepare(fitted, test.X)
    assert method._temperature(fitted) == fitted.model.temperature_
    np.testing.assert_allclose(method.evidence(fitted, state, None), fitted.model.evidence(state), atol=1e-12)
