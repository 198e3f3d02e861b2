"""pybullet imported without the build banner its C extension writes to stderr (docs/simulator.md).

Every module of the project imports pybullet from here, so a graph of several processes prints
no banner at all.
"""

from __future__ import annotations

import os
import sys


def _import_quietly():
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    return pybullet


pybullet = _import_quietly()
