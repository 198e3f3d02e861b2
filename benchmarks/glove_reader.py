"""Reader throughput, loss and arrival→publish latency against the pty emulator.

Throughput: emulator + :class:`GloveReader` at the glove's full rate (100 Hz) and at 10×/20× it;
received records per second over the streaming window, records lost (sent but not received,
excluding the stream's tail) and corrupt counts.  Latency: the ``glove.cyberglove`` node in a
NodeHarness whose clock is the wall clock, ticked at its ``rate_hz``; latency = publish time −
arrival time of each frame (the lead adds the Zenoh end-to-end figure).  Baselines of the same
run: the configured rate (ratio received/configured) and the tick period (ratio latency/period).

    python benchmarks/glove_reader.py [--seconds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.glove import protocol as P
from handflow.plugins.glove.emulator import GloveEmulator, constant_source
from handflow.plugins.glove.node import CyberGloveNode
from handflow.plugins.glove.reader import GloveReader, ReaderConfig


def throughput(rate_hz: float, seconds: float) -> dict:
    with GloveEmulator(constant_source(77)) as emu:
        reader = GloveReader(ReaderConfig(port=emu.path, glove_rate_hz=rate_hz)).start()
        got = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            time.sleep(0.005)
            got += reader.drain()
        reader.stop()
    got += reader.drain()
    ticks = [rec.device_time for rec, _ in got]
    arrivals = np.array([a for _, a in got], dtype=np.int64)
    span_s = (arrivals[-1] - arrivals[0]) / 1e9 if len(arrivals) > 1 else float("nan")
    sent = [t for _, t in emu.sent if t <= max(ticks)] if ticks else []
    _, counters = reader.snapshot()
    configured = P.TICK_HZ / np.prod(P.period_words(rate_hz))
    received_rate = (len(got) - 1) / span_s
    return {
        "target_hz": rate_hz,
        "configured_hz": round(float(configured), 2),
        "received": len(got),
        "frames_per_s": round(float(received_rate), 1),
        "ratio_vs_configured": round(float(received_rate / configured), 4),
        "lost": len(set(sent) - set(ticks)),
        "corrupt": int(counters["corrupt"]),
        "gaps": int(counters["gaps"]),
    }


def latency(rate_hz: float, tick_hz: float, seconds: float) -> dict:
    h = NodeHarness(CyberGloveNode, {"port": "emulator", "glove_rate_hz": rate_hz, "rate_hz": tick_hz})
    h.ctx.now_ns = time.time_ns  # wall clock, as in a live graph
    lat: list[int] = []
    publish = h.ctx.publish

    def timed_publish(port, msg, stamp_ns=None):
        publish(port, msg, stamp_ns)
        if port == "frames":
            lat.append(time.time_ns() - msg.arrival_ns)

    h.ctx.publish = timed_publish
    h.setup()
    period = 1.0 / tick_hz
    next_t = time.monotonic()
    end = next_t + seconds
    try:
        while time.monotonic() < end:
            next_t += period
            time.sleep(max(0.0, next_t - time.monotonic()))
            h.node.tick()
    finally:
        h.teardown()
    ms = np.array(lat) / 1e6
    return {
        "glove_hz": rate_hz,
        "tick_hz": tick_hz,
        "frames": len(ms),
        "median_ms": round(float(np.median(ms)), 3),
        "p99_ms": round(float(np.percentile(ms, 99)), 3),
        "tick_period_ms": round(1e3 * period, 3),
        "median_vs_tick_period": round(float(np.median(ms) / (1e3 * period)), 3),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    result = {
        "throughput": [throughput(r, args.seconds) for r in (100.0, 1000.0, 2000.0)],
        "latency": [latency(100.0, 500.0, args.seconds), latency(1000.0, 500.0, args.seconds)],
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for t in result["throughput"]:
            print(
                f"target {t['target_hz']:7.0f} Hz: {t['frames_per_s']:8.1f} frames/s "
                f"(×{t['ratio_vs_configured']:.3f} of configured {t['configured_hz']} Hz), lost {t['lost']}, corrupt {t['corrupt']}"
            )
        for t in result["latency"]:
            print(
                f"latency glove {t['glove_hz']:.0f} Hz, tick {t['tick_hz']:.0f} Hz: median {t['median_ms']} ms, "
                f"p99 {t['p99_ms']} ms ({t['median_vs_tick_period']}× tick period), n={t['frames']}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
