"""The hand that performs the cued gesture (plugins/demo/performer.py), behind demo.cued_glove."""

from __future__ import annotations

import numpy as np

from handflow.plugins.demo.gestures import Gesture
from handflow.plugins.demo.performer import CuedPerformer


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_each_cue_starts_a_new_seeded_performance_with_a_cross_fade():
    clock = Clock()
    hand = CuedPerformer(seed=1, noise=0.0, blend_s=0.4, clock=clock)
    rest = hand.joints(np.linspace(0, 2, 50))
    assert np.ptp(rest, axis=0).max() < 0.2  # the relaxed hand barely moves
    clock.t = 2.0
    hand.cue("grasp")
    assert hand.label == "grasp"
    t = 2.0 + np.linspace(0.5, 2.5, 60)
    first = hand.joints(t)
    assert np.ptp(first, axis=0).max() > 0.8  # the fingers close and open
    np.testing.assert_allclose(hand.joints([2.0]), rest[-1:], atol=0.05)  # the cross-fade starts where the hand was
    clock.t = 10.0
    hand.cue("grasp")
    second = hand.joints(t + 8.0)
    assert not np.allclose(first, second, atol=0.02)  # every repetition varies (period, amplitude)
    assert np.corrcoef(first[:, 6], Gesture("grasp", variation=False).joints(t - 2.0)[:, 6])[0, 1] > 0.5
    again = CuedPerformer(seed=1, noise=0.0, blend_s=0.4, clock=Clock())
    again.clock.t = 2.0
    again.cue("grasp")
    np.testing.assert_array_equal(again.joints(t), first)  # seeded


def test_unknown_cues_rest_and_frames_are_valid_raw_values():
    clock = Clock()
    hand = CuedPerformer(seed=0, clock=clock)
    for label in ("fist", "", "rest", "turn"):
        hand.cue(label)
        assert hand.label == ("turn" if label == "turn" else "rest")
        clock.t += 0.7
        frame = hand.frame()
        assert frame.shape == (22,) and frame.min() >= 1 and frame.max() <= 255
    assert CuedPerformer.performs("turn") and not CuedPerformer.performs("fist")
