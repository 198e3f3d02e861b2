"""A queue for waking a waiting thread that signals cannot wedge.

CPython 3.11's ``queue.SimpleQueue.get(timeout=...)`` blocks forever when a signal handler runs
across its deadline (it then waits with a negative timeout, which means "no timeout").  The node
runtime's main loop waits on such a queue and receives SIGTERM to stop and SIGUSR1 for a stack
dump, and the launcher waits for the zygote's replies while Ctrl-C may arrive.  ``queue.Queue``
waits on a ``threading.Condition``, whose lock wait checks for that case (docs/reliability.md).
"""

from __future__ import annotations

import queue


def wakeup_queue() -> queue.Queue:
    """An unbounded FIFO whose ``get(timeout=...)`` returns or raises ``queue.Empty`` in time, signals or not."""
    return queue.Queue()
