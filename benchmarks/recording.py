"""Recording and replay throughput, each against a baseline measured in the same run.

- write: ``McapWriter.write_encoded`` (lock, channel lookup, 1 s flush thread) vs the bare
  ``mcap.writer.Writer.add_message`` with the same bytes, chunk size and compression;
- read: ``iter_recording`` (stream reader with CRC checks and recovery) vs ``mcap.reader.make_reader``
  ``iter_messages`` on the same complete file;
- lock-step replay: messages/s of ``handflow replay --lockstep`` into a two-node graph vs a timed
  replay of the same recording at ``--speed 1000`` (both include launching the graph; the
  per-message figure subtracts a zero-message lock-step run).

    python benchmarks/recording.py [--json] [--messages 20000] [--repeats 5] [--replay-messages 300]

Figures are medians over the repeats (messages of 24 float64 values, JSON-encoded).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Array, Header, encode

REPO = Path(__file__).resolve().parents[1]
TOPIC = "handflow/bench/source/out"
CHUNK = 256 * 1024


def _payloads(n: int) -> list[bytes]:
    rng = np.random.default_rng(0)
    out = []
    for i in range(n):
        m = Array(data=rng.normal(size=24))
        m.header = Header("source", i + 1, 1_000_000_000 + i * 1_000_000)
        out.append(encode(m))
    return out


def _time(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def bench_write(path: Path, payloads: list[bytes]) -> tuple[float, float]:
    def ours():
        with McapWriter(path, chunk_size=CHUNK) as w:
            for i, p in enumerate(payloads):
                w.write_encoded(TOPIC, "handflow.Array", p, i, i, i)

    def bare():
        with open(path, "wb") as f:
            w = Writer(f, chunk_size=CHUNK, compression=CompressionType.ZSTD)
            w.start()
            sid = w.register_schema("handflow.Array", "jsonschema", b"{}")
            cid = w.register_channel(TOPIC, "json", sid)
            for i, p in enumerate(payloads):
                w.add_message(cid, i, p, i, i)
            w.finish()

    return _time(ours), _time(bare)


def bench_read(path: Path) -> tuple[float, float]:
    def ours():
        for _ in iter_recording(path):
            pass

    def bare():
        with open(path, "rb") as f:
            for _ in make_reader(f).iter_messages():
                pass

    return _time(ours), _time(bare)


def bench_lockstep(tmp: Path, n: int) -> dict[str, float]:
    rec = tmp / "replay.mcap"
    with McapWriter(rec) as w:
        for i, p in enumerate(_payloads(n)):
            w.write_encoded(
                "handflow/rec/source/out",
                "handflow.Array",
                p,
                1_000_000_000 + i * 1_000_000,
                1_000_000_000 + i * 1_000_000,
                i + 1,
            )
    empty = tmp / "empty.mcap"
    McapWriter(empty).close()
    graph = tmp / "g.yaml"
    graph.write_text(
        "name: bench_lockstep\nexternal: {source/out: Array}\nnodes:\n"
        "  - {id: scale, plugin: basic.transform, inputs: {in: source/out}}\n"
        "  - {id: sink, plugin: basic.sink, inputs: {in: scale/out}}\n"
    )

    def replay(path: Path, *extra: str) -> float:
        return _time(
            lambda: subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "handflow.framework.cli",
                    "--log-level",
                    "WARNING",
                    "replay",
                    str(path),
                    "--into",
                    str(graph),
                    *extra,
                ],
                check=True,
                cwd=REPO,
                capture_output=True,
            )
        )

    overhead = replay(empty, "--lockstep")
    lock = replay(rec, "--lockstep")
    timed = replay(rec, "--speed", "1000")
    per_msg = (lock - overhead) / n
    return {
        "lockstep_total_s": lock,
        "lockstep_startup_s": overhead,
        "timed_total_s": timed,
        "lockstep_us_per_message": per_msg * 1e6,
        "lockstep_messages_per_s": 1 / per_msg if per_msg > 0 else float("inf"),
        "lockstep_vs_timed_total_ratio": lock / timed,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--messages", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--replay-messages", type=int, default=300)
    args = ap.parse_args()
    payloads = _payloads(args.messages)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        path = tmp / "w.mcap"
        writes = [bench_write(path, payloads) for _ in range(args.repeats)]
        with McapWriter(path, chunk_size=CHUNK) as w:
            for i, p in enumerate(payloads):
                w.write_encoded(TOPIC, "handflow.Array", p, i, i, i)
        reads = [bench_read(path) for _ in range(args.repeats)]
        lock = bench_lockstep(tmp, args.replay_messages)
    n = args.messages
    w_ours, w_bare = statistics.median(w[0] for w in writes), statistics.median(w[1] for w in writes)
    r_ours, r_bare = statistics.median(r[0] for r in reads), statistics.median(r[1] for r in reads)
    result = {
        "messages": n,
        "repeats": args.repeats,
        "write_msgs_per_s": n / w_ours,
        "baseline_write_msgs_per_s": n / w_bare,
        "write_overhead_ratio": w_ours / w_bare,
        "read_msgs_per_s": n / r_ours,
        "baseline_read_msgs_per_s": n / r_bare,
        "read_overhead_ratio": r_ours / r_bare,
        "replay_messages": args.replay_messages,
        **lock,
    }
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:32s} {v:,.3f}" if isinstance(v, float) else f"{k:32s} {v}")


if __name__ == "__main__":
    main()
