"""The local transport (iceoryx2 between the processes of one graph host) against bare iceoryx2 and bare Zenoh.

The ``local`` section of ``python benchmarks/transport.py --json`` (docs/benchmarks.md,
docs/shared_memory.md); alone: ``python benchmarks/local_transport.py [--pairs 3] [--seconds 3]
[--hd-seconds 60]``.

* One hop, publisher process → subscriber process (latency from the stamp, taken once the frame
  is in the sample, to the subscriber's callback), ``Image`` payloads of 4 KiB, 4 MiB and 32 MiB at
  30 Hz, as back-to-back (handflow, bare) pairs.  handflow: the node runtime's path (a source
  fills a ``ctx.allocate`` array, here a copy of the frame's pixels, then ``NodeContext.publish``:
  header, check, ``OutputPort.publish``, which sends the sample the pixels are in; the subscriber
  decodes and validates, ``wire.unpack`` on the view into the sample).  Bare iceoryx2: the same CDR
  bytes written into a loaned sample with the raw iceoryx2 API (stamp and seq patched in), the stamp
  read on the subscriber without decoding; both wake on an iceoryx2 event.  Keys ``flat_ratio``
  (handflow p50 at 32 MiB / 4 KiB) and ``vs_bare_iceoryx2`` (handflow / bare at 4 MiB), medians of
  the pairs.
* Three processes (publisher → relay → subscriber): handflow's relay forwards the received message
  (``wire.repack`` of the view: a copy into a new sample), bare iceoryx2's relay copies the received
  bytes into a new sample (iceoryx2 cannot republish a received sample); 1080p and 4K RGB at
  30 fps: lost frames and the chain's CPU (% of one core, the three processes summed):
  ``hd_lost``, ``uhd_lost``, ``hd_cpu_percent``, ``uhd_cpu_percent``, and ``chain_4MiB`` against
  the bare relay.
* ``joint_state_vs_bare_zenoh``: ``benchmarks/transport.py``'s 24-joint chain at 1 kHz as a graph
  (three node processes, the default ``transport: {local: iceoryx2}``) against the bare Zenoh relay
  chain carrying the same CDR bytes; the median of the pairs' ratios.  ``--hogs N`` measures only
  this, with N busy-looping processes running (one per core: the loaded case).
* ``--soak SECONDS``: 1080p RGB at 30 fps through the three handflow processes for that long; lost
  frames, and the growth from a quarter of the run to its end of each process's RSS (whole, private
  and mapped shared-memory pages, as ``transport.py --shm-soak`` reports them) and of the
  shared-memory files the chain maps (bytes allocated in ``/dev/shm``).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from timing import paced

ONE_HOP = {"4KiB": 4 << 10, "4MiB": 4 << 20, "32MiB": 32 << 20}
FRAMES = {"hd": 1920 * 1080 * 3, "uhd": 3840 * 2160 * 3}
RATE_HZ = 30.0
TOPICS = ("bench/a", "bench/b")


def _bare(run: str):
    """Raw iceoryx2 ports on the services handflow uses (its service settings), for the baseline."""
    from handflow.framework.network import local_transport as lt

    t = lt.LocalTransport(run, "bench/bare")
    return t, t._services, t._iox


def _mapped_shm() -> dict[str, int]:
    """The ``/dev/shm`` files this process maps, with the bytes allocated to each."""
    paths = {
        line.split(maxsplit=5)[5] for line in Path("/proc/self/maps").read_text().splitlines() if " /dev/shm/" in line
    }
    return {p: Path(p).stat().st_blocks * 512 for p in paths if Path(p).exists()}


def _memory() -> dict:
    """RSS parts and mapped shared-memory files, sampled for ``--soak``."""
    from transport import _rss_kb

    return {"rss_kb": _rss_kb(), "shm": _mapped_shm()}


def _role(args: argparse.Namespace) -> None:
    """One process: ``args.role`` pub/relay/sub, ``args.mode`` handflow/bare."""
    from handflow.framework import wire
    from handflow.framework.messages import Header, Image
    from handflow.framework.network import local_transport as lt
    from handflow.framework.runtime.local_routes import OutputPort

    transport, services, iox = _bare(args.run)
    rows: list[tuple[int, int]] = []
    cpu0 = time.process_time()
    memory = []  # a quarter into the run and at its end
    threading.Timer(args.warmup + args.seconds / 4, lambda: memory.append(_memory())).start()
    src = TOPICS[0] if args.role == "relay" else TOPICS[args.hops - 1]  # what a relay or subscriber reads
    dst = TOPICS[1] if args.role == "relay" else TOPICS[0]  # what a relay or publisher writes

    def bare_publisher(topic):
        pubsub, event = services(topic)
        pub = pubsub.publisher_builder().initial_max_slice_len(lt.INITIAL_BYTES)
        pub = pub.allocation_strategy(iox.AllocationStrategy.PowerOfTwo).override_sample_preallocation(lt.FRAME_SAMPLES)
        pub = pub.create()
        return pub, event.notifier_builder().create()

    def bare_send(ports, data: memoryview | bytes):
        pub, notifier = ports
        sample = pub.loan_slice_uninit(len(data))
        sample.payload().as_memory_view().cast("B")[:] = data
        sample.assume_init().send()
        notifier.notify()

    if args.role == "pub":
        handflow_pub = OutputPort(None, transport.publisher(dst, bulky=True)) if args.mode == "handflow" else None
        bare_pub = bare_publisher(dst) if args.mode == "bare" else None
        data = np.empty(args.size, np.uint8)  # the pixels a source has to publish (a camera's frame)
        data[:] = np.arange(args.size) % 251
        frame = Image(width=args.size, height=1, encoding="mono8", step=args.size, data=data)
        body = bytearray(wire.pack(frame)[0])
        time.sleep(args.warmup)
        for seq in paced(args.rate, args.seconds):
            if handflow_pub is not None:  # the source fills a ctx.allocate array, then NodeContext.publish
                pixels = handflow_pub.allocate(args.size)
                pixels[:] = data
                msg = Image(width=args.size, height=1, encoding="mono8", step=args.size, data=pixels)
                msg.header = Header("pub", seq, time.time_ns())
                msg.check()
                handflow_pub.publish(msg, None, lambda payload: payload)
                continue
            sample = bare_pub[0].loan_slice_uninit(len(body))  # the frame written into a loaned sample
            view = sample.payload().as_memory_view().cast("B")
            view[:] = body
            now = time.time_ns()
            struct.pack_into("<iI", view, 4, now // 1_000_000_000, now % 1_000_000_000)
            struct.pack_into("<q", view, len(body) - 8, seq)  # the bare subscriber reads seq from here
            sample.assume_init().send()
            bare_pub[1].notify()
        time.sleep(1.0)
    elif args.mode == "handflow":
        out = transport.publisher(dst, bulky=True) if args.role == "relay" else None

        def on(payload, att):
            msg = wire.unpack(payload, att)
            if out is not None:  # the runner's forwarding of an unchanged message
                out.send(*(wire.repack(msg, payload) or wire.pack(msg)))
            else:
                rows.append((msg.header.seq, time.time_ns() - msg.header.stamp_ns))

        transport.subscribe(src, on, bulky=True)  # image topics, as the runtime makes them
        transport.start()
        sys.stdin.read()  # until run_chain closes it, after the publisher ended
        transport.stop()
    else:
        pubsub, event = services(src)
        sub, listener = pubsub.subscriber_builder().create(), event.listener_builder().create()
        out = bare_publisher(dst) if args.role == "relay" else None
        stop = threading.Event()

        def loop():
            while not stop.is_set():
                listener.timed_wait(iox.Duration.from_millis(200))
                while (sample := sub.receive()) is not None:
                    s = sample.payload()
                    view = (ctypes.c_uint8 * s.len()).from_address(s.as_ptr())
                    if out is not None:
                        bare_send(out, memoryview(view).cast("B"))
                        continue
                    sec, nsec = struct.unpack_from("<iI", view, 4)
                    (seq,) = struct.unpack_from("<q", view, s.len() - 8)
                    rows.append((seq, time.time_ns() - sec * 1_000_000_000 - nsec))

        thread = threading.Thread(target=loop, daemon=True)
        thread.start()
        sys.stdin.read()  # until run_chain closes it, after the publisher ended
        stop.set()
        thread.join()
    memory.append(_memory())
    Path(args.out).write_text(json.dumps({"rows": rows, "cpu_s": time.process_time() - cpu0, "memory": memory}))


def run_chain(size: int, mode: str, hops: int, seconds: float, rate: float = RATE_HZ) -> dict:
    """``hops`` + 1 processes of :func:`_role` on their own services; latency stats, lost, CPU of the chain."""
    from transport import _stats

    run = f"bench{time.monotonic_ns()}"
    roles = ("sub", "relay", "pub") if hops == 2 else ("sub", "pub")
    with tempfile.TemporaryDirectory() as tmp:
        outs = {r: Path(tmp) / f"{r}.json" for r in roles}
        base = [sys.executable, __file__, "--_role", "--run", run, "--mode", mode, "--size", str(size)]
        base += ["--rate", str(rate), "--seconds", str(seconds), "--hops", str(hops)]
        procs = []
        for r in roles:
            procs.append(subprocess.Popen([*base, "--role", r, "--out", str(outs[r])], stdin=subprocess.PIPE))
            time.sleep(0.3)  # subscribers before publishers
        procs[-1].wait(timeout=seconds + 120)
        for p in reversed(procs[:-1]):  # the relay first, then the subscriber, each once it had time to finish
            time.sleep(1.0)
            p.stdin.close()
            p.wait(timeout=60)
        res = {r: json.loads(o.read_text()) for r, o in outs.items()}
    rows = res["sub"]["rows"]
    stats = _stats([lat for _, lat in rows], [s for s, _ in rows], int(seconds * rate))
    return {**stats, "cpu_percent": 100 * sum(r["cpu_s"] for r in res.values()) / seconds, "memory": _soak(res)}


def _soak(res: dict) -> dict:
    """Growth from a quarter of the run to its end: each process's RSS parts, and the chain's shared memory."""
    from transport import _growth

    def shm(i: int) -> int:
        return sum({p: b for r in res.values() for p, b in r["memory"][i]["shm"].items()}.values())

    return {
        "rss_growth": {r: _growth([m["rss_kb"] for m in v["memory"]]) for r, v in res.items()},
        "rss_kb": {r: v["memory"][-1]["rss_kb"] for r, v in res.items()},
        "shm_bytes": [shm(0), shm(-1)],
        "shm_growth": shm(-1) / max(shm(0), 1) - 1,
    }


def run_local(pairs: int, seconds: float, hd_seconds: float, joint_seconds: float) -> dict:
    """The ``local`` section (module docstring)."""
    one_hop = {}
    for name, size in ONE_HOP.items():
        runs = [{m: run_chain(size, m, 1, seconds) for m in ("handflow", "bare")} for _ in range(pairs)]
        one_hop[name] = {
            "runs": runs,
            "handflow_p50_us": statistics.median(r["handflow"]["median_us"] for r in runs),
            "bare_p50_us": statistics.median(r["bare"]["median_us"] for r in runs),
            "vs_bare_iceoryx2": statistics.median(r["handflow"]["median_us"] / r["bare"]["median_us"] for r in runs),
        }
        print(
            f"local one hop {name}: " + json.dumps({k: v for k, v in one_hop[name].items() if k != "runs"}),
            file=sys.stderr,
        )
    chain = {m: run_chain(ONE_HOP["4MiB"], m, 2, seconds) for m in ("handflow", "bare")}
    frames = {name: run_chain(size, "handflow", 2, hd_seconds) for name, size in FRAMES.items()}
    joint = joint_state_pairs(pairs, joint_seconds)
    return {
        "one_hop": one_hop,
        "chain_4MiB": {**chain, "vs_bare_iceoryx2_relay": chain["handflow"]["median_us"] / chain["bare"]["median_us"]},
        "frames": frames,
        "joint_state": joint,
        "joint_state_vs_bare_zenoh": joint["ratio_median"],
        "flat_ratio": statistics.median(
            a["handflow"]["median_us"] / b["handflow"]["median_us"]
            for a, b in zip(one_hop["32MiB"]["runs"], one_hop["4KiB"]["runs"])
        ),
        "vs_bare_iceoryx2": one_hop["4MiB"]["vs_bare_iceoryx2"],
        **{f"{n}_lost": frames[n]["lost"] for n in FRAMES},
        **{f"{n}_cpu_percent": frames[n]["cpu_percent"] for n in FRAMES},
    }


def with_hogs(n: int, fn):
    """``fn()`` while ``n`` processes spin (a CPU hog per core), stopped afterwards."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        return fn()
    finally:
        for h in hogs:
            h.kill()
            h.wait()


def joint_state_pairs(pairs: int, seconds: float) -> dict:
    """The 24-joint chain at 1 kHz, graph (local transport) against the bare Zenoh relay chain."""
    from transport import _paired, run_handflow, run_raw

    return _paired(
        pairs,
        lambda: run_handflow(1000.0, seconds, 2, "joint_state"),
        lambda: run_raw(1000.0, seconds, 2, "joint_state", mode="raw"),
    )


KEYS = (
    "joint_state_vs_bare_zenoh",
    "flat_ratio",
    "vs_bare_iceoryx2",
    "hd_lost",
    "uhd_lost",
    "hd_cpu_percent",
    "uhd_cpu_percent",
)
"""The section's headline keys (issue's "Done when"; docs/benchmarks.md)."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=3.0, help="per one-hop and relay run")
    ap.add_argument("--hd-seconds", type=float, default=60.0, help="per 1080p and 4K stream")
    ap.add_argument("--joint-seconds", type=float, default=6.0, help="per 24-joint chain run")
    ap.add_argument("--json", action="store_true", help="everything, not only the headline keys")
    ap.add_argument("--hogs", type=int, default=0, help="only the 24-joint pairs, with this many CPU hogs")
    ap.add_argument("--soak", type=float, metavar="SECONDS", help="only the 1080p30 soak of that length")
    ap.add_argument("--_role", action="store_true", help=argparse.SUPPRESS)
    for name in ("--role", "--run", "--mode", "--out"):
        ap.add_argument(name, help=argparse.SUPPRESS)
    ap.add_argument("--size", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--hops", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--rate", type=float, default=RATE_HZ, help=argparse.SUPPRESS)
    ap.add_argument("--warmup", type=float, default=1.0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._role:
        _role(args)
        return
    if args.soak:
        res = run_chain(FRAMES["hd"], "handflow", 2, args.soak)
        print(json.dumps({k: res[k] for k in ("received", "lost", "median_us", "cpu_percent", "memory")}))
        return
    if args.hogs:
        res = with_hogs(args.hogs, lambda: joint_state_pairs(args.pairs, args.joint_seconds))
        pairs = [(p["handflow_chain"]["median_us"], p["raw_chain"]["median_us"], p["ratio"]) for p in res["pairs"]]
        lost = [p["handflow_chain"]["lost"] for p in res["pairs"]]
        print(json.dumps({"joint_state_vs_bare_zenoh": res["ratio_median"], "pairs_us": pairs, "lost": lost}))
        return
    res = run_local(args.pairs, args.seconds, args.hd_seconds, args.joint_seconds)
    print(json.dumps(res if args.json else {k: res[k] for k in KEYS}))


if __name__ == "__main__":
    main()
