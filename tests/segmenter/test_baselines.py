import numpy as np

from handflow.plugins.segmenter import PerClassHMM, SlidingDTW1NN


def test_baselines_classify_clean_synthetic_letters(synthetic):
    train = synthetic.by_class("train")
    # chance level is 0.25 (4 classes); a 10-sample window of a closed curve is ambiguous for an HMM
    for model, bar in ((SlidingDTW1NN(window=10), 0.6), (PerClassHMM(n_states=4, window=10), 0.4)):
        model.fit(train)
        acc = [np.mean(np.array(model.classes_)[model.predict(t.data)] == t.label) for t in synthetic.test]
        assert np.mean(acc) > bar, type(model).__name__


def test_baseline_threshold_rejects(synthetic):
    model = SlidingDTW1NN(window=5).fit(synthetic.by_class("train"))
    model.threshold = np.inf
    assert np.all(model.predict(synthetic.test[0].data) == -1)
