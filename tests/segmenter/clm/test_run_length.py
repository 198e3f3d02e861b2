"""CLMSegmenter's ``run_length``: long sequences solved in overlapping runs (docs/segmentation.md,
"Long recordings")."""

import numpy as np
import pytest

from handflow.plugins.segmenter.clm import CLMSegmenter, default_solver, run_stretches
from handflow.plugins.segmenter.compatibility import evidence_band


def _evidence(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Noisy evidence of three classes in segments of 60–200 frames, and the true classes."""
    rng = np.random.default_rng(seed)
    truth = np.concatenate([np.full(rng.integers(60, 200), rng.integers(3)) for _ in range(n // 60)])[:n]
    evidence = rng.uniform(0.0, 0.6, size=(n, 3))
    evidence[np.arange(n), truth] += 1.0
    evidence = np.hstack([evidence, np.full((n, 1), 0.3)])  # a null class: the background's layer
    return evidence / evidence.sum(axis=1, keepdims=True), truth


def _segmenter(run_length):
    return CLMSegmenter(
        None, reconstruction="relative", solver=default_solver(max_sweeps=300), run_length=run_length, random_state=0
    )


def _labels(seg: CLMSegmenter, evidence: np.ndarray) -> np.ndarray:
    _, span, width = seg.widths()
    return seg.fit_predict_bands(*seg.with_background(evidence_band(evidence, width, span)))


@pytest.mark.parametrize("n", [1, 999, 1000, 1001, 4321])
def test_the_kept_parts_tile_the_sequence_inside_runs_of_at_most_run_length(n):
    stretches = run_stretches(n, 1000, 80)
    kept = [(a, b) for _, _, a, b in stretches]
    assert kept[0][0] == 0 and kept[-1][1] == n
    assert all(b == next_a for (_, b), (next_a, _) in zip(kept, kept[1:]))
    for lo, hi, a, b in stretches:
        assert hi - lo <= 1000 and lo <= a < b <= hi
        assert (a == 0 or a - lo == 80) and (b == n or hi - b == 80)
    assert run_stretches(n, None, 80) == [(0, n, 0, n)]


def test_a_sequence_within_run_length_is_solved_as_one_run():
    evidence, _ = _evidence(900)
    whole = _segmenter(None)
    labels = _labels(whole, evidence)
    short = _segmenter(1000)
    assert np.array_equal(_labels(short, evidence), labels)
    assert np.array_equal(short.activities_, whole.activities_) and short.energy_ == whole.energy_


def test_runs_over_a_long_sequence_label_it_as_one_run_does():
    evidence, truth = _evidence(5000, seed=1)
    whole = _labels(_segmenter(None), evidence)
    seg = _segmenter(1024)
    runs = _labels(seg, evidence)
    assert (whole == truth).mean() > 0.9
    assert (runs == whole).mean() > 0.98
    assert seg.activities_.shape == (4, 5000) and seg.labels_.shape == (5000,)
    assert np.array_equal(seg.labels_, np.where(seg.result_.winners == 3, -1, seg.result_.winners))


def test_a_run_length_shorter_than_its_margins_need_is_refused():
    seg = _segmenter(300)  # margins of 8 band widths of H = 10: 80 observations each
    assert seg.run_margin == 80
    with pytest.raises(ValueError, match="run_length must be at least 320 observations"):
        _labels(seg, _evidence(100)[0])
