import numpy as np
import pytest

from handflow.plugins.segmenter import PerClassHMM, SlidingDTW1NN


@pytest.mark.parametrize("name", ["dtw", "hmm"])
def test_baselines_classify_clean_synthetic_letters(synthetic, name):
    if name == "hmm":
        pytest.importorskip("hmmlearn", reason="the HMM baseline is the extra 'hmm'")
    train = synthetic.by_class("train")
    # chance level is 0.25 (4 classes); a 10-sample window of a closed curve is ambiguous for an HMM
    model, bar = {"dtw": (SlidingDTW1NN(window=10), 0.6), "hmm": (PerClassHMM(n_states=4, window=10), 0.4)}[name]
    model.fit(train)
    acc = [np.mean(np.array(model.classes_)[model.predict(t.data)] == t.label) for t in synthetic.test]
    assert np.mean(acc) > bar, type(model).__name__


def test_baseline_threshold_rejects(synthetic):
    model = SlidingDTW1NN(window=5).fit(synthetic.by_class("train"))
    model.threshold = np.inf
    assert np.all(model.predict(synthetic.test[0].data) == -1)


def test_dtw_references_are_capped_by_whole_segments():
    """Below the cap every segment is thinned to every 4th frame; above it evenly spaced whole
    thinned segments stay within the cap, so labelling costs time linear in the recording."""
    from handflow.plugins.segmenter.scorers import dtw_references

    segs = [np.full((100, 2), float(i)) for i in range(50)]  # 25 thinned frames each, 1 250 in all
    assert [len(r) for r in dtw_references(segs)] == [25] * 50
    capped = dtw_references(segs, max_frames=300)
    assert sum(map(len, capped)) <= 300 and all(len(r) == 25 for r in capped)
    kept = [int(r[0, 0]) for r in capped]
    assert kept == sorted(kept) and kept[0] == 0 and kept[-1] >= 40  # spread over the whole class
    assert [len(r) for r in dtw_references([np.zeros((20, 2))])] == [20]  # short segments keep every frame
