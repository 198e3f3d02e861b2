"""Scripted hand gestures for the flagship demo: motion classes, a script, recordings, a dataset.

Four periodic motion classes in the 24-joint human hand model (``handflow.plugins.hands.joints.HUMAN``):

- ``grasp``: all fingers and the thumb close and open together (small per-finger lags);
- ``wave``: sequential finger flexion, index → little (a quarter cycle apart);
- ``pinch``: thumb–index tapping, the other fingers resting half-curled;
- ``turn``: a cap-turning-like cycle: half-closed fingers circling against the thumb while the
  wrist rotates (flexion and wrist yaw a quarter cycle apart, so the posture runs a loop).

Each class is a :class:`GestureSpec` (per joint: offset and amplitude in degrees around
:data:`NEUTRAL_DEG`, lag in cycles, wave ``0.5 − 0.5 cos``); :class:`Gesture` is one seeded
performance of it with human-like variation (documented choice: period ×U(0.9, 1.1), amplitude
×U(0.9, 1.1) per performance and ×U(0.95, 1.05) per joint, lags +N(0, 0.01) cycles, and a slow
time warp of ±3 % of a cycle); every joint also moves a little in the gesture's rhythm
(:data:`SYMPATHETIC`).  Finger spread follows the glove mapping's spread constraint
(index and little spread equally, middle and ring a third of it).

:class:`GestureScript` plays classes one after another for given durations with a short
cross-fade (``blend_s``) and reports the ground-truth label per time.  Its raw glove frames (the
inverse sensor model of :class:`handflow.plugins.glove.synthetic.SyntheticGlove`) are what the flagship's
emulated glove plays (``emulator.frames``), so no plugin imports another at run time.

The flagship's models come from the project itself (docs/flagship.md)::

    python -m handflow.plugins.demo.gestures frames --out configs/models/gestures/demo_frames.npy
    python -m handflow.plugins.demo.gestures record --out recordings/gestures.mcap
    python -m handflow.plugins.demo.gestures dataset recordings/gestures.mcap --out out/gestures_dataset.npz
    handflow train-classes out/gestures_dataset.npz --out configs/models/gestures --steps 200

``record`` runs every gesture through the glove chain as plain classes — inverse sensor model →
integer raw frames → :class:`~handflow.plugins.mapping.human.HumanHandMapping` →
:class:`~handflow.plugins.mapping.robot.ShadowHandMapping`, the same code the graph nodes wrap — and writes
the frames, the ShadowHand joints and one ``SegmentEvent`` per demonstration to MCAP.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.files.mcap_writer import McapWriter, RecordingError
from handflow.framework.messages import GloveFrame, JointState, SegmentEvent
from handflow.plugins.glove.synthetic import SyntheticGlove
from handflow.plugins.hands.joints import DEG, HUMAN, SHADOW
from handflow.plugins.mapping.robot import ShadowHandMapping

GRAPH = "gestures"
"""Graph name in the topics of a gesture recording (``handflow/gestures/<node>/<port>``)."""
FRAMES_TOPIC = f"handflow/{GRAPH}/glove/frames"
JOINTS_TOPIC = f"handflow/{GRAPH}/shadow/joints"
TRUTH_TOPIC = f"handflow/{GRAPH}/script/truth"

SEGMENT_JOINTS: tuple[str, ...] = (
    "WRJ2",
    "WRJ1",
    "FFJ4",
    "FFJ3",
    "FFJ2",
    "MFJ3",
    "MFJ2",
    "RFJ3",
    "RFJ2",
    "LFJ5",
    "LFJ3",
    "LFJ2",
    "THJ4",
    "THJ2",
    "THJ1",
)
"""ShadowHand joints the gesture classes are recognised from (documented choice): the coupled distal
J1s repeat J2, THJ3 is passive, the middle/ring spread barely moves, and the thumb base rotation
THJ5 swings strongly near the analytic thumb mapping's singularity, so it would dominate the
normalised reconstruction error.  The flagship's segmenter uses the same list (``joints:``)."""

NEUTRAL_DEG: dict[str, float] = {
    "wrist_pitch": 0.0,
    "wrist_yaw": 0.0,
    "palm_arch": 5.0,
    "th_abduction": 45.0,
    "th_roll": 20.0,
    "th_mcp_side": 0.0,
    "th_mcp": 10.0,
    "th_ip": 10.0,
    **{f"{f}_{j}": v for f in ("ff", "mf", "rf", "lf") for j, v in (("mcp", 15.0), ("pip", 20.0), ("dip", 10.0))},
}
"""Relaxed hand (degrees); joints a gesture does not name stay here.  Spread joints follow ``phi``."""
NEUTRAL_PHI_DEG = 10.0
"""Total finger spread Φ of the relaxed hand (index and little spread −Φ/2, middle and ring −Φ/6)."""

Wave = tuple[float, float, float]
"""(offset °, amplitude °, lag in cycles): ``q = neutral + offset + amplitude · (0.5 − 0.5 cos 2π(φ − lag))``."""


@dataclass(frozen=True)
class GestureSpec:
    """A periodic motion class: its nominal period and a :data:`Wave` per moving joint (``phi`` = spread)."""

    name: str
    period_s: float
    waves: dict[str, Wave] = field(default_factory=dict)


def _fingers(
    mcp: Wave, pip: Wave, dip: Wave, lag_step: float = 0.0, only: tuple[str, ...] = ("ff", "mf", "rf", "lf")
) -> dict[str, Wave]:
    """The same flexion waves on several fingers, each ``lag_step`` cycles after the previous one."""
    out = {}
    for k, f in enumerate(only):
        for joint, (off, amp, lag) in (("mcp", mcp), ("pip", pip), ("dip", dip)):
            out[f"{f}_{joint}"] = (off, amp, lag + k * lag_step)
    return out


SYMPATHETIC: dict[str, Wave] = {
    "wrist_pitch": (0, 8, 0.1),
    "wrist_yaw": (0, 6, 0.2),
    "palm_arch": (0, 6, 0.0),
    "th_abduction": (0, 8, 0.0),
    "th_roll": (0, 8, 0.05),
    "th_mcp": (0, 8, 0.1),
    "th_ip": (0, 8, 0.15),
    **_fingers((0, 10, 0.0), (0, 10, 0.05), (0, 8, 0.1), lag_step=0.05),
    "phi": (0, 5, 0.3),
}
"""Small motion of every joint in the gesture's rhythm, under each gesture's own waves (documented
choice: a hand never holds a joint perfectly still while moving the others, and a class whose
training data holds a joint still would have a near-zero variance there, so glove noise alone would
dominate the normalised reconstruction error ``e_t`` of the recognisers)."""

GESTURES: dict[str, GestureSpec] = {
    g.name: g
    for g in (
        GestureSpec(
            "grasp",
            1.6,
            {
                **_fingers((0, 60, 0.0), (0, 75, 0.04), (0, 50, 0.07), lag_step=0.03),
                "th_abduction": (0, 30, 0.0),
                "th_roll": (0, 40, 0.0),
                "th_mcp": (0, 30, 0.05),
                "th_ip": (0, 35, 0.08),
                "palm_arch": (0, 20, 0.0),
                "phi": (15, -20, 0.0),
            },
        ),
        GestureSpec(
            "wave",
            1.8,
            {
                **_fingers((0, 65, 0.0), (0, 75, 0.04), (0, 50, 0.06), lag_step=0.25),
                "wrist_pitch": (0, 12, 0.3),
                "phi": (0, 15, 0.5),
            },
        ),
        GestureSpec(
            "pinch",
            1.0,
            {
                **_fingers((10, 40, 0.0), (10, 45, 0.02), (0, 30, 0.04), only=("ff",)),
                **_fingers((20, 10, 0.1), (30, 10, 0.15), (15, 8, 0.2), only=("mf", "rf", "lf")),
                "th_abduction": (10, 35, 0.0),
                "th_roll": (20, 40, 0.0),
                "th_mcp": (0, 25, 0.02),
                "th_ip": (0, 30, 0.04),
                "phi": (-5, 5, 0.0),
            },
        ),
        GestureSpec(
            "turn",
            2.0,
            {
                **_fingers((20, 20, 0.25), (20, 20, 0.3), (10, 15, 0.3), lag_step=0.02),
                "wrist_yaw": (-12, 24, 0.0),
                "wrist_pitch": (-5, 10, 0.5),
                "th_abduction": (15, 20, 0.5),
                "th_roll": (25, 15, 0.5),
                "th_mcp": (15, 15, 0.55),
                "phi": (0, 10, 0.25),
            },
        ),
    )
}
"""The flagship's motion classes (see the module docstring)."""


class Gesture:
    """One seeded performance of a :class:`GestureSpec`: ``joints(t)`` → (n, 24) human-model postures."""

    def __init__(self, spec: GestureSpec | str, seed: int = 0, variation: bool = True) -> None:
        self.spec = GESTURES[spec] if isinstance(spec, str) else spec
        rng = np.random.default_rng(seed)
        waves = {**SYMPATHETIC, **self.spec.waves}
        names = list(waves)
        scale = lambda lo, hi, size=None: rng.uniform(lo, hi, size) if variation else np.ones(size or ())  # noqa: E731
        self.period_s = self.spec.period_s * float(scale(0.9, 1.1))
        amp = float(scale(0.9, 1.1)) * scale(0.95, 1.05, len(names))
        lag_jitter = rng.normal(0.0, 0.01, len(names)) if variation else np.zeros(len(names))
        self.warp = 0.03 if variation else 0.0
        self.warp_phase = float(rng.uniform(0, 2 * np.pi))
        waves = np.array([waves[n] for n in names], dtype=float).reshape(-1, 3)
        self._names = names
        self._offset = waves[:, 0] * DEG
        self._amp = waves[:, 1] * DEG * amp
        self._lag = waves[:, 2] + lag_jitter

    def phase(self, t) -> np.ndarray:
        """Motion phase in cycles at times ``t`` (with the slow time warp)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        cycles = t / self.period_s
        return cycles + self.warp * np.sin(2 * np.pi * cycles / 3.3 + self.warp_phase) / (2 * np.pi)

    def joints(self, t) -> np.ndarray:
        phase = self.phase(t)[:, None] - self._lag
        values = self._offset + self._amp * (0.5 - 0.5 * np.cos(2 * np.pi * phase))
        q = np.tile(np.array([NEUTRAL_DEG.get(n, 0.0) * DEG for n in HUMAN.names]), (len(phase), 1))
        phi = np.full(len(phase), NEUTRAL_PHI_DEG * DEG)
        for k, name in enumerate(self._names):
            if name == "phi":
                phi = phi + values[:, k]
            else:
                q[:, HUMAN.index(name)] += values[:, k]
        return HUMAN.clip(with_spread(q, phi))


def with_spread(q: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Postures ``q`` with the finger spread of total angle ``phi`` under the glove's spread constraint."""
    q = q.copy()
    for f, share in (("ff", 0.5), ("lf", 0.5), ("mf", 1 / 6), ("rf", 1 / 6)):
        q[:, HUMAN.index(f"{f}_spread")] = -share * phi
    return q


@dataclass(frozen=True)
class Segment:
    """One entry of a script: gesture ``label`` from ``start_s`` for ``duration_s``."""

    label: str
    start_s: float
    duration_s: float

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s


DEMO_SCRIPT: tuple[tuple[str, float], ...] = (("grasp", 8.0), ("wave", 8.0), ("pinch", 8.0), ("turn", 8.0))
"""The flagship's default script (32 s, looped by the emulated glove)."""


class GestureScript:
    """Gestures one after another; ``joints(t)``, ``labels(t)``, raw glove ``frames(rate_hz)``.

    Entering a segment, the posture cross-fades from the previous gesture over ``blend_s`` (the
    ground-truth label switches at the segment start).  Each segment is a new seeded performance.
    """

    def __init__(self, steps=DEMO_SCRIPT, seed: int = 0, blend_s: float = 0.4, variation: bool = True) -> None:
        steps = [(str(label), float(d)) for label, d in steps]
        unknown = sorted({label for label, _ in steps} - set(GESTURES))
        if unknown or not steps:
            raise ValueError(f"unknown gesture(s) {unknown} in the script; choose from {sorted(GESTURES)}")
        if any(d <= blend_s for _, d in steps):
            raise ValueError(f"every script step must last longer than blend_s = {blend_s} s")
        self.segments, start = [], 0.0
        for label, d in steps:
            self.segments.append(Segment(label, start, d))
            start += d
        seeds = np.random.SeedSequence(seed).spawn(len(steps))
        self.gestures = [
            Gesture(s.label, int(ss.generate_state(1)[0]), variation) for s, ss in zip(self.segments, seeds)
        ]
        self.blend_s = blend_s

    @property
    def duration_s(self) -> float:
        return self.segments[-1].end_s

    def _segment_index(self, t: np.ndarray) -> np.ndarray:
        starts = np.array([s.start_s for s in self.segments])
        return np.clip(np.searchsorted(starts, np.mod(t, self.duration_s), side="right") - 1, 0, len(starts) - 1)

    def labels(self, t) -> list[str]:
        """Ground-truth gesture at times ``t`` (the script loops)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return [self.segments[i].label for i in self._segment_index(t)]

    def joints(self, t) -> np.ndarray:
        t = np.mod(np.atleast_1d(np.asarray(t, dtype=float)), self.duration_s)
        seg = self._segment_index(t)
        q = np.empty((len(t), len(HUMAN)))
        for i, (s, g) in enumerate(zip(self.segments, self.gestures)):
            here = seg == i
            if not here.any():
                continue
            local = t[here] - s.start_s
            q[here] = g.joints(local)
            fading = local < self.blend_s
            if fading.any():  # previous gesture (the last one before the first: the script loops)
                prev, ps = self.gestures[i - 1], self.segments[i - 1]
                w = (0.5 - 0.5 * np.cos(np.pi * local[fading] / self.blend_s))[:, None]
                q[np.flatnonzero(here)[fading]] = (1 - w) * prev.joints(ps.duration_s + local[fading]) + w * q[here][
                    fading
                ]
        return q

    def frames(self, rate_hz: float, noise: float = 0.5, seed: int = 0) -> np.ndarray:
        """Raw CyberGlove frames (n, 22) of one pass of the script at ``rate_hz``."""
        t = np.arange(int(round(self.duration_s * rate_hz))) / rate_hz
        return SyntheticGlove(self, noise=noise, seed=seed).frames(t)


# ----------------------------------------------------------------------------------------------
# Recording demonstrations and turning them into a labelled dataset
# ----------------------------------------------------------------------------------------------
def record_gestures(
    path: str | Path,
    sequences: int = 5,
    duration_s: float = 3.6,
    rate_hz: float = 50.0,
    noise: float = 0.5,
    seed: int = 0,
    gestures: list[str] | None = None,
) -> dict[str, int]:
    """Record ``sequences`` performances of every gesture through the glove chain to MCAP.

    Topics: :data:`FRAMES_TOPIC` (GloveFrame), :data:`JOINTS_TOPIC` (ShadowHand JointState, stamp =
    the frame's) and :data:`TRUTH_TOPIC` (one ``SegmentEvent`` ``end`` per demonstration, indices
    into the joint stream).  Demonstrations are 1 s apart in time.  Returns the message counts.
    """
    names = gestures or sorted(GESTURES)
    shadow = ShadowHandMapping()
    t = np.arange(int(round(duration_s * rate_hz))) / rate_hz
    seeds = iter(np.random.SeedSequence(seed).spawn(len(names) * sequences))
    index, start_ns = 0, 0
    with McapWriter(path, flush_interval_s=None) as w:
        for label in names:
            for _k in range(sequences):
                s = int(next(seeds).generate_state(1)[0])
                glove = SyntheticGlove(Gesture(label, s), noise=noise, seed=s)
                raw = glove.frames(t)
                q = shadow.map(glove.mapping.map(raw))
                stamps = start_ns + (t * 1e9).astype(np.int64)
                for frame, joints, stamp in zip(raw, q, stamps):
                    w.write(FRAMES_TOPIC, GloveFrame(sensors=frame, arrival_ns=int(stamp)), int(stamp), int(stamp))
                    w.write(
                        JOINTS_TOPIC,
                        JointState(names=SHADOW.names, positions=joints, hand=SHADOW.name),
                        int(stamp),
                        int(stamp),
                    )
                w.write(
                    TRUTH_TOPIC,
                    SegmentEvent(kind="end", label=label, start_index=index, end_index=index + len(t) - 1),
                    int(stamps[-1]),
                    int(stamps[-1]),
                )
                index += len(t)
                start_ns = int(stamps[-1]) + 1_000_000_000
        counts = dict(w.counts)
    return counts


def gesture_dataset(recording: str | Path, out: str | Path, joints: tuple[str, ...] = SEGMENT_JOINTS) -> dict[str, int]:
    """Cut a gesture recording into a labelled ``.npz`` (arrays ``<label>_<k>`` of the ShadowHand
    ``joints``, in that order) for ``handflow train-classes``; returns the sequences per label."""
    rows, segments = [], []
    for topic, msg, _ in read_messages(recording):
        if topic == JOINTS_TOPIC:
            missing = sorted(set(joints) - set(msg.names))
            if missing:
                raise ValueError(f"{recording}: the joint stream lacks {missing}; record ShadowHand joints")
            rows.append(msg.positions[[msg.names.index(j) for j in joints]])
        elif topic == TRUTH_TOPIC:
            segments.append(msg)
    if not rows or not segments:
        raise RecordingError(
            f"{recording} has no '{JOINTS_TOPIC}' joints or no '{TRUTH_TOPIC}' segments; "
            "record it with `python -m handflow.plugins.demo.gestures record`"
        )
    Y = np.stack(rows)
    arrays, per_label = {}, {}
    for ev in segments:
        k = per_label.get(ev.label, 0)
        arrays[f"{ev.label}_{k}"] = Y[ev.start_index : ev.end_index + 1]
        per_label[ev.label] = k + 1
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        out, **arrays, metadata=np.array(json.dumps({"columns": list(joints), "source": str(recording)}))
    )
    return per_label


# ----------------------------------------------------------------------------------------------
# Command line: python -m handflow.plugins.demo.gestures {frames,record,dataset}
# ----------------------------------------------------------------------------------------------
def _script_steps(text: str) -> list[tuple[str, float]]:
    try:
        return [(label, float(d)) for label, d in (item.split(":") for item in text.split(","))]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--script must look like grasp:8,wave:8 (gesture:seconds,...), got {text!r}"
        ) from None


def register(parser: argparse.ArgumentParser) -> None:
    """Gesture demonstrations: the flagship's glove frames, recordings, and a training dataset."""
    sub = parser.add_subparsers(dest="what", required=True, metavar="WHAT")
    fr = sub.add_parser("frames", help="raw glove frames (.npy) of a gesture script, for emulator.frames")
    fr.add_argument("--out", required=True, help="output .npy (n × 22 raw values)")
    fr.add_argument(
        "--script",
        type=_script_steps,
        default=list(DEMO_SCRIPT),
        help=f"gesture:seconds,... (default {','.join(f'{g}:{d:g}' for g, d in DEMO_SCRIPT)})",
    )
    fr.add_argument("--rate", type=float, default=50.0, help="glove rate in Hz (the graph's glove_rate_hz)")
    fr.add_argument("--seed", type=int, default=0)
    rec = sub.add_parser("record", help="record every gesture through the glove chain to MCAP")
    rec.add_argument("--out", required=True, help="output .mcap")
    rec.add_argument("--sequences", type=int, default=5, help="demonstrations per gesture (≥ 3)")
    rec.add_argument("--duration", type=float, default=3.6, help="seconds per demonstration")
    rec.add_argument("--rate", type=float, default=50.0)
    rec.add_argument("--seed", type=int, default=0)
    rec.add_argument("--gestures", help=f"comma-separated subset of {','.join(sorted(GESTURES))}")
    ds = sub.add_parser("dataset", help="cut a gesture recording into a labelled .npz for train-classes")
    ds.add_argument("recording")
    ds.add_argument("--out", required=True, help="output .npz")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        if args.what == "frames":
            script = GestureScript(args.script, seed=args.seed)
            frames = script.frames(args.rate, seed=args.seed)
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            np.save(args.out, frames.astype(np.uint8))
            print(
                f"wrote {len(frames)} frames ({script.duration_s:g} s at {args.rate:g} Hz: "
                + ", ".join(f"{s.label} {s.start_s:g}–{s.end_s:g} s" for s in script.segments)
                + f") to {args.out}"
            )
        elif args.what == "record":
            if args.sequences < 3:
                raise ValueError("--sequences must be ≥ 3 (train-classes splits them into train/validation/test)")
            gestures = args.gestures.split(",") if args.gestures else None
            unknown = sorted(set(gestures or []) - set(GESTURES))
            if unknown:
                raise ValueError(f"unknown gesture(s) {unknown}; choose from {sorted(GESTURES)}")
            counts = record_gestures(
                args.out, args.sequences, args.duration, args.rate, seed=args.seed, gestures=gestures
            )
            print(f"wrote {sum(counts.values())} messages to {args.out}")
        else:
            per_label = gesture_dataset(args.recording, args.out)
            print(
                f"wrote {sum(per_label.values())} sequences ({', '.join(f'{k}: {v}' for k, v in per_label.items())}) "
                f"to {args.out}"
            )
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m handflow.plugins.demo.gestures", description=register.__doc__)
    register(parser)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
