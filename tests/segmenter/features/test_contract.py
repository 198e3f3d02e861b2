"""Every causal transform follows one streaming contract: ``fit`` returns the transform,
``transform`` a whole recording, ``stream().push`` the same rows frame by frame; the online
recognisers' per-sample method is ``push`` too, ``update`` its alias
(plugins/segmenter/features/_contract.py, docs/segmentation.md)."""

import numpy as np
import pytest

from handflow.plugins.segmenter.clm import UKROnlyRecognizer
from handflow.plugins.segmenter.features import (
    CausalTransform,
    ChannelScaling,
    DelayEmbedding,
    Derived,
    Headings,
    RunningStandardizer,
    SampleStream,
)
from handflow.plugins.segmenter.online import OnlineCLMSegmenter

RNG = np.random.default_rng(0)
TRAIN = RNG.normal(2.0, 3.0, size=(60, 3))
X = np.cumsum(RNG.normal(size=(25, 3)), axis=0)

TRANSFORMS = {
    "delay": lambda: DelayEmbedding(3, 2).fit(TRAIN),
    "derived": lambda: Derived("velocities").fit(TRAIN),
    "headings": lambda: Headings((0, 1)).fit([TRAIN]),
    "running_scaling": lambda: RunningStandardizer().fit(TRAIN),
    "scaling": lambda: ChannelScaling().fit([TRAIN]),
}


@pytest.mark.parametrize("name", sorted(TRANSFORMS))
def test_a_transform_streams_what_it_transforms(name):
    transform = TRANSFORMS[name]()
    assert isinstance(transform, CausalTransform)
    stream = transform.stream()
    assert isinstance(stream, SampleStream)
    np.testing.assert_array_equal(np.array([stream.push(x) for x in X]), transform.transform(X))


@pytest.mark.parametrize(
    "make", [lambda: DelayEmbedding(3, 2), lambda: Derived("velocities"), lambda: Headings((0, 1)), ChannelScaling]
)
def test_fit_returns_the_transform_itself(make):
    transform = make()
    assert transform.fit([TRAIN]) is transform


def test_running_scaling_keeps_update_as_the_alias_of_push():
    scaler = RunningStandardizer().fit(TRAIN)
    pushed, updated = scaler.stream(), scaler.stream()
    np.testing.assert_array_equal([pushed.push(x) for x in X], [updated.update(x) for x in X])


def test_online_recognisers_push_like_they_update(candidates, two_letters):
    Y = two_letters[0][:40]
    for make in (
        lambda: UKROnlyRecognizer(candidates, history=10),
        lambda: OnlineCLMSegmenter(candidates, history=10, window=30, random_state=0),
    ):
        pushed, updated = make(), make()
        assert isinstance(pushed, SampleStream)
        a = [pushed.push(y) for y in Y]
        b = [updated.update(y) for y in Y]
        assert repr(a) == repr(b)
