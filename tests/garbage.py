"""An outside Zenoh peer that joins a running graph and publishes garbage onto its inputs (docs/robustness.md)."""

from __future__ import annotations

import threading
import time
from collections import defaultdict

import numpy as np
from hypothesis import strategies as st

from handflow.framework import wire
from handflow.framework.messages import encode
from handflow.framework.observe.monitor import Monitor
from handflow.framework.testkit.fuzzing import (
    BYTE_OPS,
    Mutation,
    malformed_payloads,
    mutate,
    random_mutations,
    sample_messages,
)

# the original killer: a glove frame whose sensors are all 1e308
HUGE_GLOVE = (
    b'{"type":"handflow.GloveFrame","header":{"source":"x","seq":1,"stamp_ns":1},"sensors":['
    + b",".join([b"1e308"] * 22)
    + b"]}"
)


def mutate_bytes(data: bytes, rng: np.random.Generator) -> bytes:
    return mutate(data, [Mutation(BYTE_OPS[m.value % 3], m.position, m.value) for m in random_mutations(rng)])


def damaged_file(draw, raw: bytes) -> bytes:
    """``raw`` truncated, or with 1–4 bytes changed; ``draw`` is hypothesis' ``st.data().draw``."""
    out = bytearray(raw)
    if draw(st.booleans()):
        return bytes(out[: draw(st.integers(0, len(out) - 1))])
    for _ in range(draw(st.integers(1, 4))):
        out[draw(st.integers(0, len(out) - 1))] = draw(st.integers(0, 255))
    return bytes(out)


class GarbagePeer:
    """Collects real payloads of ``topics`` from the graph, then publishes mutated ones onto them."""

    def __init__(self, session, graph: str, topics: list[str]) -> None:
        self.session = session
        self.topics = topics
        self.real: dict[str, list[tuple[bytes, bytes | None]]] = defaultdict(list)
        self._lock = threading.Lock()
        self._subs = [session.declare_subscriber(t, self._collect) for t in topics]
        self.monitor = Monitor(session, graph)

    def _collect(self, sample) -> None:
        with self._lock:
            bucket = self.real[str(sample.key_expr)]
            if len(bucket) < 20:
                bucket.append(wire.sample_parts(sample))

    def ready(self, nodes: int) -> bool:
        with self._lock:
            have_all = all(len(self.real[t]) >= 5 for t in self.topics)
        snap = self.monitor.snapshot()
        return have_all and sum(n["alive"] for n in snap["nodes"]) >= nodes

    def nodes(self) -> dict[str, dict]:
        return {n["id"]: n for n in self.monitor.snapshot()["nodes"]}

    def publish(self, per_topic: int, seed: int = 0) -> int:
        """``per_topic`` samples per topic: real CDR payloads with mutated bytes or attachments, every other
        message type (CDR and JSON), JSON garbage without attachment, random bytes."""
        samples = sample_messages()
        others = [wire.pack(m) for m in samples] + [(encode(m), None) for m in samples]
        rng = np.random.default_rng(seed)
        pubs = {t: self.session.declare_publisher(t) for t in self.topics}
        sent = 0
        for k, (topic, pub) in enumerate(pubs.items()):
            with self._lock:
                real = list(self.real[topic])
            garbage = [(HUGE_GLOVE, None), *others, (rng.bytes(64), None), (rng.bytes(64), real[0][1])]
            n = (per_topic - len(garbage)) // 3
            for i in range(n):  # CDR bodies mutated under a real attachment
                body, att = real[i % len(real)]
                garbage.append((mutate_bytes(body, rng), att))
            for i in range(n):  # real bodies under mutated attachments
                body, att = real[i % len(real)]
                garbage.append((body, mutate_bytes(att, rng)))
            json_seeds = [encode(m) for m in samples]
            garbage += [(p, None) for p in malformed_payloads(per_topic - len(garbage), seed + k, json_seeds)]
            for payload, att in garbage:
                pub.put(payload, attachment=att)
                sent += 1
                time.sleep(0.001)
        for pub in pubs.values():
            pub.undeclare()
        return sent

    def close(self) -> None:
        for s in self._subs:
            s.undeclare()
        self.monitor.close()
