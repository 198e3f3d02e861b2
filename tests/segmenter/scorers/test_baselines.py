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
