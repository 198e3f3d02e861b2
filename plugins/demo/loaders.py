"""Loading the demonstration recordings of ``handflow demo-record`` (layout: :mod:`handflow.plugins.demo.demonstrations`).

Both loaders find their topics by suffix (``…/sim/joints``, ``…/demo/label``,
``…/demo/observation``), so a recording of a real glove session with the same ports loads too,
and pair messages by identical log time.  They raise :class:`ValueError` naming the missing
topic or the command that records the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from handflow.framework.files.mcap_reader import read_messages


def _by_suffix(path, suffixes: tuple[str, ...]) -> dict[str, list[tuple[int, object]]]:
    path = Path(path)
    if not path.is_file():
        raise ValueError(
            f"demonstration recording {path} not found; record one with `handflow demo-record cap|balls --out {path}`"
        )
    out: dict[str, list[tuple[int, object]]] = {s: [] for s in suffixes}
    for topic, msg, log_time in read_messages(path):
        for s in suffixes:
            if topic.endswith("/" + s):
                out[s].append((log_time, msg))
    missing = [s for s, found in out.items() if not found]
    if missing:
        raise ValueError(
            f"{path} has no messages on …/{', …/'.join(missing)}; is it a "
            f"`handflow demo-record` recording of the right task?"
        )
    return out


def load_cap_demonstrations(path) -> list[tuple[dict, np.ndarray, list[str]]]:
    """Cap-turning sequences in recording order: ``(meta, postures, joint_names)`` per sequence.

    ``meta = {"radius_m": float, "sequence": int}``; ``postures`` (n, 24) are the collision-corrected
    ShadowHand-like joint angles in posture order.
    """
    found = _by_suffix(path, ("sim/joints", "demo/label"))
    labels = {t: dict(zip(m.names, m.data.tolist())) for t, m in found["demo/label"]}
    rows: dict[int, list[np.ndarray]] = {}
    radius: dict[int, float] = {}
    names: list[str] = []
    for t, js in found["sim/joints"]:
        label = labels.get(t)
        if label is None:
            continue
        seq = int(label["sequence"])
        rows.setdefault(seq, []).append(js.positions)
        radius[seq] = float(label["radius"])
        names = list(js.names)
    return [({"radius_m": radius[s], "sequence": s}, np.vstack(rows[s]), names) for s in rows]


def load_ball_demonstrations(path) -> list[tuple[dict, np.ndarray, list[str]]]:
    """Ball-swapping observations per swap cycle: ``(meta, observations, names)``.

    ``observations`` (n, 20) = 16 independent Gifu joints, p1, p2 (normalised tracked balls);
    ``meta = {"swap_cycle": int, "time_s": (n,), "hand_cycle": (n,), "hand_phase": (n,)}`` with
    the time from the start of the recording.  One swap cycle (ball period) spans two hand cycles.
    """
    found = _by_suffix(path, ("demo/observation", "demo/label"))
    labels = {t: dict(zip(m.names, m.data.tolist())) for t, m in found["demo/label"]}
    cycles: dict[int, list[tuple[int, np.ndarray, dict]]] = {}
    names: list[str] = []
    for t, obs in found["demo/observation"]:
        label = labels.get(t)
        if label is None:
            continue
        cycles.setdefault(int(label["swap_cycle"]), []).append((t, obs.data, label))
        names = list(obs.names)
    out = []
    for c, rows in cycles.items():
        meta = {
            "swap_cycle": c,
            "time_s": np.array([t for t, _, _ in rows]) * 1e-9,
            "hand_cycle": np.array([int(lab["hand_cycle"]) for _, _, lab in rows]),
            "hand_phase": np.array([lab["hand_phase"] for _, _, lab in rows]),
        }
        out.append((meta, np.vstack([d for _, d, _ in rows]), names))
    return out
