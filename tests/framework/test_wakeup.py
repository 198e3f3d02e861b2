"""The runtime's wake-up queue returns in time when a signal handler runs across its deadline (framework/runtime/wakeup.py)."""

from __future__ import annotations

import subprocess
import sys

PROBE = """
import queue, signal, time
from handflow.framework.runtime.wakeup import wakeup_queue

q = wakeup_queue()
signal.signal(signal.SIGALRM, lambda *_: time.sleep(0.02))  # the handler runs past the wait's deadline
for _ in range(20):
    signal.setitimer(signal.ITIMER_REAL, 0.09)
    t0 = time.monotonic()
    try:
        q.get(timeout=0.1)
    except queue.Empty:
        pass
    assert time.monotonic() - t0 < 1.0
print("ok")
"""


def test_a_signal_at_the_deadline_does_not_wedge_the_wait():
    # with queue.SimpleQueue (CPython 3.11) the first wait never returns: SIGTERM then could not stop a node
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=30)
    assert out.stdout.strip() == "ok", out.stderr
