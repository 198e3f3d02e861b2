"""Live parameters end to end (docs/tuning.md): `handflow param` on a running configs/basic_chain.yaml over
real Zenoh sessions and processes, the change on the graph's parameter topic and in its recordings."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from handflow.framework import keys, wire
from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.messages import Array, ParamChange
from handflow.framework.runtime.discovery import join, live_runs

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
GRAPH = "basic_chain"


def gain_of(msg: Array) -> float:
    """The gain scale/out was computed with: basic_chain's source is a 3-phase sine (its squares sum to
    1.5 whatever the phase) and the offset is 0.5."""
    return float(np.sqrt(np.sum((np.asarray(msg.data) - 0.5) ** 2) / 1.5))


class Listener:
    """scale/out and the parameter topic of the running graph, from a session of our own."""

    def __init__(self) -> None:
        self.session, _ = join(GRAPH)
        self.lock = threading.Lock()
        self.outputs: list[Array] = []
        self.changes: list[ParamChange] = []
        self.subs = [
            self.session.declare_subscriber(keys.topic_key(GRAPH, "scale", "out"), self._on(self.outputs)),
            self.session.declare_subscriber(keys.params_key(GRAPH), self._on(self.changes)),
        ]

    def _on(self, into: list):
        def callback(sample) -> None:
            with self.lock:
                into.append(wire.unpack(*wire.sample_parts(sample)))

        return callback

    def outputs_for(self, seconds: float) -> list[Array]:
        with self.lock:
            start = len(self.outputs)
        time.sleep(seconds)
        with self.lock:
            return self.outputs[start:]

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()
        self.session.close()


def handflow(*args: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.fixture
def running_chain(tmp_path, monkeypatch):
    """configs/basic_chain.yaml running with --record, and `handflow record` of scale's topics beside it."""
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    env = dict(__import__("os").environ)
    run = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", "configs/basic_chain.yaml", "--duration", "40"]
        + ["--record", str(tmp_path / "run.mcap")],
        cwd=REPO,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 30
    while not live_runs():
        assert time.monotonic() < deadline and run.poll() is None, "the graph did not start"
        time.sleep(0.1)
    record = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "record", GRAPH, "--out", str(tmp_path / "outside.mcap")]
        + ["--topics", "scale/*"],
        cwd=REPO,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    listener = Listener()
    time.sleep(1.5)  # the recorder and the listener joined
    yield env, run, record, listener
    listener.close()
    for proc in (record, run):
        if proc.poll() is None:
            proc.terminate()
        proc.communicate(timeout=60)


def test_param_set_changes_the_running_stream_and_bad_values_are_refused(running_chain, tmp_path):
    env, run, record, listener = running_chain
    before = listener.outputs_for(2.2)  # a full period of the 0.5 Hz sine
    assert before and max(float(np.max(m.data)) for m in before) == pytest.approx(2.5, abs=0.05)

    done = handflow("param", "set", "scale.gain", "3", env=env)
    assert done.returncode == 0, done.stderr
    after = listener.outputs_for(2.2)
    assert max(float(np.max(m.data)) for m in after) == pytest.approx(3.5, abs=0.05)
    assert handflow("param", "get", "scale.gain", env=env).stdout.strip() == "3"

    refused = handflow("param", "set", "scale.gain", "notanumber", env=env)
    assert refused.returncode == 1
    assert "scale.gain" in refused.stderr and "valid number" in refused.stderr  # the model's message
    assert handflow("param", "get", "scale.gain", env=env).stdout.strip() == "3"  # the old value kept
    assert np.allclose([gain_of(m) for m in listener.outputs_for(0.5)], 3.0)

    start_only = handflow("param", "set", "source.rate_hz", "20", env=env)
    assert start_only.returncode == 1 and "needs a restart" in start_only.stderr and "--restart" in start_only.stderr
    unknown = handflow("param", "set", "scale.gian", "3", env=env)
    assert unknown.returncode == 2 and "has no parameter 'gian'" in unknown.stderr and "gain" in unknown.stderr

    # the one accepted change is on the parameter topic, stamped with the first input handled with it
    with listener.lock:
        changes, outputs = list(listener.changes), list(listener.outputs)
    assert [(c.node, c.key, json.loads(c.value), json.loads(c.previous)) for c in changes] == [
        ("scale", "gain", 3.0, 2.0)
    ]
    stamp = changes[0].header.stamp_ns
    assert all(gain_of(m) == pytest.approx(2.0 if m.header.stamp_ns < stamp else 3.0) for m in outputs)
    assert stamp in {m.header.stamp_ns for m in outputs}

    listing = handflow("param", "list", "scale", env=env)
    assert listing.stdout.splitlines() == ["scale.gain = 3  (live)", "scale.offset = 0.5  (live)"]

    record.terminate()
    record.communicate(timeout=60)
    run.terminate()
    _, err = run.communicate(timeout=60)
    assert run.returncode == 0, err
    for recording in ("run.mcap", "outside.mcap"):  # --record, and `handflow record --topics scale/*`
        recorded = [m for t, m, _ in read_messages(tmp_path / recording) if t == keys.params_key(GRAPH)]
        assert [(m.key, m.value, m.header.stamp_ns) for m in recorded] == [("gain", "3.0", stamp)], recording


def test_restart_takes_a_start_only_parameter_restarting_that_node_alone(running_chain):
    env, run, record, listener = running_chain
    done = handflow("param", "set", "source.rate_hz", "20", "--restart", env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "source.rate_hz = 20"
    assert handflow("param", "get", "source.rate_hz", env=env).stdout.strip() == "20"
    arrivals = listener.outputs_for(2.0)
    assert 30 <= len(arrivals) <= 50  # 20 Hz now (50 Hz before)
    with listener.lock:
        changes = list(listener.changes)
    assert [(c.node, c.key, c.value, c.restart) for c in changes] == [("source", "rate_hz", "20.0", True)]
    run.terminate()
    _, err = run.communicate(timeout=60)
    assert err.count("started source (pid") == 2  # restarted once …
    assert err.count("started scale (pid") == 1 and err.count("started sink (pid") == 1  # … and alone
