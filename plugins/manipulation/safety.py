"""The controllers' declared fail-safe posture: an open hand.

Documented choice: "open" = every joint of the hand model at 0 rad (extended fingers, neutral
thumb and wrist), clipped to the joint limits; ``overrides`` (joint name → rad) change single
joints, e.g. a wider thumb.
"""

from __future__ import annotations

import numpy as np

from handflow.framework.messages import JointState
from handflow.plugins.hands.joints import HAND_MODELS


def open_hand(hand: str, overrides: dict[str, float] | None = None) -> JointState:
    """JointState of the open hand of model ``hand`` (all of its joints)."""
    model = HAND_MODELS[hand]
    q = np.zeros(len(model))
    for name, value in (overrides or {}).items():
        q[model.index(name)] = value
    return JointState(names=list(model.names), positions=model.clip(q), hand=hand)
