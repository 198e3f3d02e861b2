"""Errors a newcomer meets say what to do: no display, ports in use, no glove, no model."""

from __future__ import annotations

import logging
import os
import socket
import subprocess
import sys

import pytest

from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.glove.node import CyberGloveNode, serial_ports
from handflow.plugins.segmenter.models import ModelsMissingError
from handflow.plugins.segmenter.nodes import OnlineCLMNode
from tests.conftest import REPO, handflow

GUI_MODULES = ("tkinter", "PyQt5", "PyQt6", "PySide2", "PySide6", "gi", "wx")


def test_nothing_needs_a_display():
    """Every framework and plugin module imports and plots headless; no GUI toolkit is loaded."""
    code = f"""
import importlib, pkgutil, sys
import handflow.framework, handflow.plugins
for pkg in (handflow.framework, handflow.plugins):
    for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
        importlib.import_module(m.name)
from handflow.plugins.segmenter import plots   # the modules that draw
from handflow.plugins.mapping import zero_abduction
import matplotlib
assert matplotlib.get_backend().lower() == "agg", matplotlib.get_backend()
gui = [m for m in {GUI_MODULES!r} if m in sys.modules]
assert not gui, gui
print("ok")
"""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MPLBACKEND")}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=REPO, timeout=120)
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr[-3000:]


def test_zenoh_listen_endpoint_in_use_says_what_to_change(tmp_path):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        graph = tmp_path / "g.yaml"
        graph.write_text(f"""name: busy
zenoh: {{listen: ["tcp/127.0.0.1:{port}"]}}
nodes:
  - id: source
    plugin: basic.signal
""")
        proc = handflow("run", str(graph), "--duration", "1", timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert f"tcp/127.0.0.1:{port}" in proc.stderr and "already in use" in proc.stderr
    assert "zenoh: {listen" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_missing_glove_device_lists_ports_and_suggests_the_emulator(caplog):
    h = NodeHarness(CyberGloveNode, {"port": "/dev/ttyHANDFLOW_NOPE", "stall_timeout_s": 0.1})
    with caplog.at_level(logging.ERROR):
        h.setup()
    try:
        text = caplog.text
        assert "/dev/ttyHANDFLOW_NOPE not found" in text
        assert "port: emulator" in text
        assert f"serial ports on this machine: {', '.join(serial_ports()) or 'none'}" in text
    finally:
        h.teardown()


def test_existing_device_or_emulator_gives_no_such_hint(caplog):
    from handflow.plugins.glove.node import missing_device_message

    assert missing_device_message("emulator") is None
    assert missing_device_message("bt://00:11:22:33:44:55") is None
    assert missing_device_message("/dev/null") is None


def test_missing_model_says_how_to_train_it(tmp_path):
    h = NodeHarness(OnlineCLMNode, {"models": str(tmp_path / "models" / "gestures")})
    with pytest.raises(ModelsMissingError, match="handflow train-classes"):
        h.setup()
