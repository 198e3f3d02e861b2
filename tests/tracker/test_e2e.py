"""simulator.pybullet → tracker.color_blobs through the real runtime (Zenoh, one process per node)."""

import subprocess
import sys
from collections import Counter

import pytest

from handflow.framework.files.mcap_reader import read_messages

GRAPH = """name: sim_e2e
nodes:
  - id: sim
    plugin: simulator.pybullet
    params: {hand: gifu, scene: balls, rate_hz: 30, camera_hz: 5, camera_width: 240, camera_height: 180}
  - id: tracker
    plugin: tracker.color_blobs
    inputs: {image: sim/image}
"""


@pytest.mark.slow
def test_simulated_camera_feeds_the_tracker(tmp_path):
    graph = tmp_path / "balls.yaml"
    graph.write_text(GRAPH)
    rec = tmp_path / "rec.mcap"
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--duration", "4", "--record", str(rec)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    counts, balls = Counter(), []
    for topic, msg, _ in read_messages(rec):
        counts[topic.rsplit("/", 2)[-2] + "/" + topic.rsplit("/", 1)[-1]] += 1
        if topic.endswith("tracker/balls"):
            balls.append(msg)
    assert counts["sim/joints"] >= 30 and counts["tracker/balls"] >= 5
    assert all(b.valid.all() for b in balls)  # both resting balls are seen in every frame
