"""Large payloads through Zenoh shared memory between real processes (docs/shared_memory.md)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading

import pytest
import zenoh

from handflow.framework import wire
from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.network import shm
from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.observe.monitor import Monitor
from tests.framework._rec_helpers import start, unique, wait_until, write_graph

pytestmark = pytest.mark.skipif(not shm.available(), reason="eclipse-zenoh without the shared-memory API")

WIDTH = 16384  # 128 KiB of float64 per message: above shm.THRESHOLD


@pytest.fixture(autouse=True)
def private_run_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))


def _graph(tmp_path, name: str, port: int, shared_memory: bool):
    return write_graph(
        tmp_path / f"{name}.yaml",
        name,
        f"""zenoh: {{listen: [tcp/127.0.0.1:{port}], shared_memory: {json.dumps(shared_memory)}}}
nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: noise, rate_hz: 20, width: {WIDTH}, seed: 3}}
  - id: sink
    plugin: basic.sink
    inputs: {{in: source/out}}
""",
    )


def _peer(port: int, shared_memory: bool) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    shm.configure(conf, shared_memory)
    return zenoh.open(conf)


def _record(tmp_path, shared_memory: bool, peers: dict | None = None) -> dict[int, bytes]:
    """Run the graph for a few seconds with ``--record``; ``{seq: CDR payload}`` of the recorded source topic."""
    name, port = unique(f"shm{int(shared_memory)}"), free_tcp_port()
    out = tmp_path / f"{name}.mcap"
    proc = start("run", str(_graph(tmp_path, name, port, shared_memory)), "--record", str(out), "--duration", "5")
    try:
        if peers is not None:
            sessions = {mode: _peer(port, mode == "shm") for mode in ("shm", "net")}
            for mode, s in sessions.items():
                peers[mode] = {"samples": {}, "monitor": Monitor(s, name), "session": s}
                s.declare_subscriber(
                    f"handflow/{name}/source/out",
                    lambda sample, got=peers[mode]["samples"]: got.__setitem__(
                        wire.parse_attachment(sample.attachment.to_bytes())[2],
                        (sample.payload.to_bytes(), shm.via_shm(sample.payload)),
                    ),
                )
            wait_until(lambda: all(len(p["samples"]) >= 20 for p in peers.values()), timeout=40, what="20 samples each")
            for peer in peers.values():
                peer["snapshot"] = peer["monitor"].snapshot()
                peer["session"].close()
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    return {m.sequence: m.data for m in iter_recording(out, [f"handflow/{name}/source/out"])}


def test_shared_memory_carries_the_same_bytes_as_the_network(tmp_path):
    peers: dict = {}
    with_shm = _record(tmp_path, True, peers)
    got_shm, got_net = peers["shm"]["samples"], peers["net"]["samples"]
    # a peer with shared memory reads the buffers, one with it off gets the bytes over TCP: the same bytes
    assert sum(via for _, via in got_shm.values()) >= len(got_shm) - 2  # lazy set-up: the first may be bytes
    assert not any(via for _, via in got_net.values())
    common = sorted(set(got_shm) & set(got_net))
    assert len(common) >= 15 and all(got_shm[s][0] == got_net[s][0] for s in common)
    # the recording (the launcher's hub reads through shared memory too) holds what was published
    assert all(with_shm[s] == got_shm[s][0] for s in common if s in with_shm)
    topic = {t["topic"].rsplit("/", 2)[-2]: t["shm"] for t in peers["shm"]["snapshot"]["topics"]}
    assert topic["source"] is True  # the monitor shows the topic travelling through shared memory
    assert not any(t["shm"] for t in peers["net"]["snapshot"]["topics"])

    # the same seeded graph with `shared_memory: false`: a byte-identical recording but for the stamps
    without = _record(tmp_path, False)
    both = sorted(set(with_shm) & set(without))
    assert len(both) >= 40
    for s in both:
        a, b = with_shm[s], without[s]
        assert len(a) > shm.THRESHOLD and a[:4] + a[12:] == b[:4] + b[12:]  # bytes 4..12: the header stamp


HOLDER = textwrap.dedent(
    """
    import json, sys, time, zenoh
    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
    session = zenoh.open(conf)
    kept = []  # every buffer stays referenced until this process is killed
    session.declare_subscriber("shmtest/x", lambda s: (kept.append(s.payload), print(len(kept), flush=True)))
    time.sleep(120)
    """
)


def _segment_size(name: str) -> int | None:
    try:
        return os.path.getsize(f"/dev/shm/{name}")
    except FileNotFoundError:  # removed between the listing and the look (a pool closing elsewhere)
        return None


def _our_segments(size: int) -> set[str]:
    return {f for f in os.listdir("/dev/shm") if f.endswith(".zenoh") and _segment_size(f) == size}


def test_buffers_held_by_a_killed_process_never_block_publishing_and_its_pool_is_reclaimed(tmp_path):
    port = free_tcp_port()
    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    session = zenoh.open(conf)
    # every payload must arrive: Zenoh's default drops a message whose queue stays full for a
    # millisecond, which a 256 KiB payload sent over the network meets on a loaded machine
    pub = session.declare_publisher("shmtest/x", congestion_control=zenoh.CongestionControl.BLOCK)
    pool = shm.SharedPayloads(True, pool_bytes=1 << 20)  # room for three 256 KiB buffers (and headers)
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, f"tcp/127.0.0.1:{port}"], stdout=subprocess.PIPE, text=True
    )
    counts: list[str] = []  # the holder's count after each payload
    threading.Thread(target=lambda: counts.extend(line.strip() for line in holder.stdout), daemon=True).start()
    try:
        # the holder's subscriber is routed (a fixed pause lost the first payload on a loaded machine)
        wait_until(lambda: pub.matching_status.matching, timeout=60, what="the holder's subscriber")
        for i in range(6):
            pub.put(pool.wrap(bytes([i]) * (256 << 10)))
            wait_until(lambda n=i + 1: len(counts) >= n, timeout=60, what=f"the holder's receipt of payload {i + 1}")
        assert counts == [str(i + 1) for i in range(6)]
        # the holder pins every buffer: the pool ran out and later payloads went over the network
        assert pool.sent >= 2 and pool.fallbacks >= 1 and pool.sent + pool.fallbacks == 6
    finally:
        holder.kill()
        holder.wait()
        session.close()

    # a node process killed while owning a pool: its segment stays until the next Zenoh process on
    # this host sets up shared memory and removes segments whose owner is gone
    size = 5 * 1024 * 1024 + 65536  # a pool size no other process here uses
    before = _our_segments(size)
    owner = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import time; from handflow.framework.network import shm\n"
            f"p = shm.SharedPayloads(True, pool_bytes={size}); p.wrap(bytes(1 << 20)); print('ok', flush=True)\n"
            "time.sleep(120)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert owner.stdout.readline().strip() == "ok"
    left = _our_segments(size) - before
    owner.send_signal(signal.SIGKILL)
    owner.wait()
    assert left and left <= _our_segments(size), "the killed process's segment is still there"
    fresh = subprocess.run(
        [
            sys.executable,
            "-c",
            "from handflow.framework.network import shm; shm.SharedPayloads(True).wrap(bytes(1 << 17))",
        ],
        timeout=60,
    )
    assert fresh.returncode == 0
    wait_until(lambda: not (left & _our_segments(size)), timeout=10, what="the orphaned segment removed")
