"""Decoding robustness at scale: 100 000 malformed payloads through ``messages.decode`` (docs/robustness.md).

Payloads are mutated copies (:mod:`handflow.framework.testkit.fuzzing`: numbers set to extremes, arrays
emptied or repeated, bytes flipped or cut) of one sample of every message type and of messages of
the shipped recordings.  Every payload must decode to a message that passes ``check()`` and
re-encodes, or raise ``MessageError``; anything else is counted as *escaped* (goal: 0).  Cost per
payload (``decode`` alone, valid or rejected) is compared with ``json.loads`` of the same payloads (baseline, same run).

    python benchmarks/decode_fuzz.py [--json] [--payloads 100000] [--seed 0]
"""

from __future__ import annotations

import argparse
import collections
import json
import statistics
import time
from pathlib import Path

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.messages import MessageError, decode, encode
from handflow.framework.testkit.fuzzing import malformed_payloads, sample_messages

RECORDINGS = Path(__file__).resolve().parents[1] / "recordings"
BATCH = 1000


def seeds(per_topic: int = 5) -> list[bytes]:
    out = [encode(m) for m in sample_messages()]
    for path in sorted(RECORDINGS.glob("*.mcap")):
        seen: collections.Counter = collections.Counter()
        for rm in iter_recording(path):
            if seen[rm.topic] < per_topic:
                seen[rm.topic] += 1
                out.append(rm.data)
    return out


def classify(payload: bytes) -> str:
    try:
        msg = decode(payload)
        msg.check()
        decode(encode(msg))
        return "valid"
    except MessageError:
        return "rejected"
    except Exception as exc:  # the figure this benchmark exists for: must stay 0
        return f"escaped:{type(exc).__name__}"


def _batch_us(fn, batch: list[bytes]) -> float:
    t = time.perf_counter()
    for p in batch:
        fn(p)
    return (time.perf_counter() - t) / len(batch) * 1e6


def _json_only(p: bytes) -> None:
    try:
        json.loads(p)
    except ValueError:
        pass


def _decode_only(p: bytes) -> None:
    try:
        decode(p)
    except MessageError:
        pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--payloads", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    payloads = list(malformed_payloads(args.payloads, args.seed, seeds()))
    outcomes: collections.Counter = collections.Counter()
    decode_us, json_us = [], []
    for i in range(0, len(payloads), BATCH):
        batch = payloads[i : i + BATCH]
        outcomes.update(classify(p) for p in batch)
        decode_us.append(_batch_us(_decode_only, batch))
        json_us.append(_batch_us(_json_only, batch))
    escaped = {k.split(":", 1)[1]: n for k, n in outcomes.items() if k.startswith("escaped:")}
    result = {
        "payloads": len(payloads),
        "valid": outcomes["valid"],
        "rejected": outcomes["rejected"],
        "escaped": sum(escaped.values()),
        "escaped_by_type": escaped,
        "median_us_per_payload": round(statistics.median(decode_us), 2),
        "baseline_json_loads_us": round(statistics.median(json_us), 2),
    }
    result["ratio_vs_json_loads"] = round(result["median_us_per_payload"] / result["baseline_json_loads_us"], 2)
    if args.json:
        print(json.dumps(result))
        return
    for k, v in result.items():
        print(f"{k:>28}: {v}")


if __name__ == "__main__":
    main()
