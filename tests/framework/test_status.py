"""The graph's status line (docs/pipelines.md): a topic's field, logged when it changes, rate-limited."""

from __future__ import annotations

import logging
import time

import numpy as np

from handflow.framework import keys, wire
from handflow.framework.graphs.model import StatusSpec
from handflow.framework.messages import Array, Label
from handflow.framework.network import sessions as transport
from handflow.framework.network.settings import ZenohSettings
from handflow.framework.runtime.status import StatusLine


def _shown(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "handflow.status"]


def test_a_value_is_shown_when_it_changes_and_at_most_once_per_interval(caplog):
    line = StatusLine("g", StatusSpec(topic="seg/labels", field="label", min_interval_s=1.0))
    with caplog.at_level(logging.INFO, logger="handflow.status"):
        for now, label in [
            (0.0, "grasp"),
            (0.5, "grasp"),
            (0.6, "wave"),
            (0.9, "grasp"),
            (1.2, "grasp"),
            (1.3, "pinch"),
            (2.0, "turn"),
            (2.4, "turn"),
        ]:
            line.show(label, now)
    # wave came too soon after grasp and had passed by 1.2 (no line for a value already shown);
    # pinch came after the interval; turn at 2.0 too soon after pinch, still current at 2.4
    assert _shown(caplog) == ["seg/labels: grasp", "seg/labels: pinch", "seg/labels: turn"]


def test_labels_published_on_zenoh_reach_the_status_line(caplog):
    hub_ep = transport.hub_endpoint_for()
    hub = transport.open_hub(ZenohSettings(), hub_ep)
    peer = transport.open_node_session(ZenohSettings(), hub_ep)
    line = StatusLine("g", StatusSpec(topic="seg/labels", field="label", min_interval_s=0.0))
    try:
        with caplog.at_level(logging.INFO, logger="handflow.status"):
            line.attach(hub)
            pub = peer.declare_publisher(keys.topic_key("g", "seg", "labels"))
            deadline = time.monotonic() + 10
            while not _shown(caplog) and time.monotonic() < deadline:  # until the subscription is matched
                _put(pub, "unknown")
                time.sleep(0.05)
            for label in ["grasp", "grasp", "wave"]:
                stray, att = wire.pack(Array(data=np.zeros(3)))  # another type on the key is passed over
                pub.put(stray, attachment=att)
                _put(pub, label)
            while len(_shown(caplog)) < 3 and time.monotonic() < deadline:
                time.sleep(0.05)
    finally:
        line.close()
        peer.close()
        hub.close()
    assert _shown(caplog) == ["seg/labels: unknown", "seg/labels: grasp", "seg/labels: wave"]
    assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]  # no callback error


def _put(pub, label: str) -> None:
    payload, att = wire.pack(Label(label=label))
    pub.put(payload, attachment=att)
