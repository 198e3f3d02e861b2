"""Transport latency and loss: handflow graph vs bare Zenoh, measured in the same run.

Setup: 24-float messages.  handflow: ``basic.signal → basic.transform → basic.sink`` (three
processes, the sink writes arrival − source stamp per message) and the single hop
``basic.signal → basic.sink`` (two processes).  24-joint states (``JointState``, names and
positions): ``basic.signal (message: joint_state) → basic.select → basic.sink`` at the top rate.  Baseline: bare Zenoh publisher → subscriber (two
processes) and publisher → relay → subscriber (three processes) with the same payload (the same
CDR bytes and attachment, docs/ros2.md), the same session topology (a hub peer plus gossip) and the
same rates.

Images: a 640×480 RGB ``Image`` at 30 Hz over one hop (two processes).  handflow: the publisher
encodes a fresh message per frame and the subscriber decodes and validates it (``wire.pack`` /
``wire.unpack``); baseline: bare Zenoh carrying the same CDR bytes (the stamp patched in place),
read without decoding.  ``image_codec_ms`` is encode + decode of one frame in-process (median);
``recording_mb_per_s`` is the sustained rate of ``McapWriter`` storing such frames (zstd chunks),
next to the bare ``mcap`` writer with the same bytes and settings.

    python benchmarks/transport.py [--json] [--seconds 6] [--rates 100 1000] [--pairs 3]
    python benchmarks/transport.py --shm [--json] [--pairs 3] [--seconds 3] [--hd-seconds 20]
    python benchmarks/transport.py --shm-soak 600

``--shm`` (docs/shared_memory.md): a payload sweep (4 KiB … 1920×1080×3 ``Image``) through three
processes (publisher → relay → subscriber, 30 Hz) as back-to-back triples: handflow (the wire and
the node process's shared-memory pool: publish packs a frame whose pixels are already in a
``ctx.allocate`` buffer, the relay decodes and forwards it, the subscriber decodes and validates
it), bare Zenoh with shared memory (a provider buffer, forwarded as is) and bare Zenoh without it
(TCP).  Latency: the publisher's ``publish`` to the subscriber's callback.  Keys ``shm.flat_ratio``
(handflow p50 at 4 MiB / 4 KiB), ``shm.vs_bare_tcp``, ``shm.vs_bare_shm`` (at 4 MiB, medians of the
pairs' ratios), ``shm.hd_lost`` and ``shm.hd_cpu_percent`` (1080p RGB at 30 fps through the three
handflow processes, CPU of the three summed, in % of one core).  ``--shm-soak SECONDS`` streams 1080p30
through the three handflow processes and reports lost frames, payloads that fell back to the network
because the pool ran short (``shm_fallbacks``) and each process's RSS growth from a quarter of the run
to its end, whole (``VmRSS``) and split into private memory (``RssAnon``) and touched pages of the mapped
shared-memory pools (``RssShmem``).

``--json`` adds the ``local`` section: the local transport (iceoryx2 between the processes of one
graph host) against bare iceoryx2 and bare Zenoh, from ``benchmarks/local_transport.py`` (its
docstring names the keys); ``--local`` runs that section alone.

``overhead_ratio`` = median latency of the handflow chain / median of the bare-Zenoh chain with
the same number of hops at the top rate, measured as ``--pairs`` back-to-back (handflow, bare)
pairs and reported as the median of the pairs' ratios (``chain_pairs``);
``overhead_ratio_single_hop`` compares the two-process set-ups;
``image_overhead_ratio`` = median image latency handflow / bare Zenoh;
``joint_state_overhead_ratio`` = the same paired ratio for 24-joint states (``joint_state``).
"""

from __future__ import annotations

import argparse
import json
import re
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

WIDTH = 24
IMAGE_SHAPE = (480, 640, 3)
IMAGE_RATE_HZ = 30.0


def _image(seq: int):
    """A rendered-looking 640×480 RGB frame: smooth gradients with sensor noise (compressible like a camera's)."""
    from handflow.framework.messages import Image

    rng = np.random.default_rng(seq)
    h, w, _ = IMAGE_SHAPE
    yy, xx = np.mgrid[0:h, 0:w]
    base = np.stack([xx * 255 // w, yy * 255 // h, (xx + yy + seq) % 256], axis=-1)
    return Image.from_array((base + rng.integers(0, 8, size=IMAGE_SHAPE)).astype(np.uint8))


# ------------------------------------------------------------------------------------------------
# bare zenoh roles (run as subprocesses of this script)
# ------------------------------------------------------------------------------------------------
def _role(args: argparse.Namespace) -> None:
    from handflow.framework import wire
    from handflow.framework.messages import Array, Header, JointState
    from handflow.framework.network import sessions as transport
    from handflow.framework.network.settings import ZenohSettings

    settings = ZenohSettings()
    session = transport.open_node_session(settings, args.hub)
    out_rows: list[tuple[int, int]] = []
    if args.role == "pub":
        pub = session.declare_publisher("bench/a")
        time.sleep(args.warmup)
        data = np.zeros(WIDTH)
        frames = [_image(i) for i in range(4)] if args.payload == "image" else []
        if frames and args.mode == "raw":  # the same CDR bytes every time; only the stamp is patched in
            body = bytearray(wire.pack(frames[0])[0])
        for seq in paced(args.rate, args.seconds):
            now = time.time_ns()
            if frames and args.mode == "raw":
                struct.pack_into("<iI", body, 4, now // 1_000_000_000, now % 1_000_000_000)
                pub.put(bytes(body), attachment=wire.attachment("handflow.Image", "pub", seq))
                continue
            if frames:
                msg = frames[seq % len(frames)]
            elif args.payload == "joint_state":
                msg = JointState(names=[f"j{k}" for k in range(WIDTH)], positions=data + seq)
            else:
                msg = Array(data=data + seq)
            msg.header = Header("pub", seq, now)
            payload, att = wire.pack(msg)
            pub.put(payload, attachment=att)
        time.sleep(1.0)
    elif args.role == "relay":
        pub = session.declare_publisher("bench/b")

        def forward(sample):
            payload, att = wire.sample_parts(sample)
            pub.put(payload, attachment=att)

        session.declare_subscriber("bench/a", forward)
        time.sleep(args.seconds + args.warmup + 2)
    else:
        read = wire.peek if args.mode == "raw" else wire.unpack

        def on(sample):
            h = read(*wire.sample_parts(sample))
            h = getattr(h, "header", h)
            out_rows.append((h.seq, time.time_ns() - h.stamp_ns))

        session.declare_subscriber(args.key, on)
        time.sleep(args.seconds + args.warmup + 2)
        Path(args.out).write_text(json.dumps(out_rows))
    session.close()


SWEEP = {"4KiB": 4 << 10, "64KiB": 64 << 10, "1MiB": 1 << 20, "4MiB": 4 << 20, "1080p": 1920 * 1080 * 3}


def _shm_role(args: argparse.Namespace) -> None:
    """One process of the ``--shm`` chain: ``args.role`` pub/relay/sub, ``args.mode`` handflow/shm/tcp."""
    import zenoh
    import zenoh.shm as _zshm

    from handflow.framework import wire
    from handflow.framework.messages import Header, Image
    from handflow.framework.network import sessions as transport
    from handflow.framework.network.settings import ZenohSettings
    from handflow.framework.network.shm import POOL_BYTES, SharedPayloads

    session = transport.open_node_session(ZenohSettings(shared_memory=args.mode != "tcp"), args.hub)
    pool = SharedPayloads(args.mode == "handflow")
    provider = _zshm.ShmProvider.default_backend(POOL_BYTES) if args.mode == "shm" else None
    rows: list[tuple[int, int]] = []
    cpu0 = time.process_time()
    rss = []  # kB after a quarter of the run and at its end (--shm-soak)
    threading.Timer(args.warmup + args.seconds / 4, lambda: rss.append(_rss_kb())).start()
    if args.role == "pub":
        pub = session.declare_publisher("bench/a")
        data = np.empty(args.size, np.uint8)  # stands for a ctx.allocate buffer the source filled in place
        data[:] = np.arange(args.size) % 251
        frame = Image(width=args.size, height=1, encoding="mono8", step=args.size, data=data)
        body = bytearray(wire.pack(frame)[0])
        time.sleep(args.warmup)
        for seq in paced(args.rate, args.seconds):
            now = time.time_ns()
            if args.mode == "handflow":  # NodeContext.publish: header, check, pack, pool
                frame.header = Header("pub", seq, now)
                frame.check()
                payload, att = wire.pack(frame)
                pub.put(pool.wrap(payload), attachment=att)
                continue
            struct.pack_into("<iI", body, 4, now // 1_000_000_000, now % 1_000_000_000)
            att = wire.attachment(Image.TYPE, "pub", seq)
            if provider is None:
                pub.put(bytes(body), attachment=att)
            else:
                buf = provider.alloc(len(body), _zshm.GarbageCollect(_zshm.JustAlloc(), _zshm.Defragment()))
                buf[0 : len(body)] = body
                pub.put(zenoh.ZBytes(buf), attachment=att)
        time.sleep(1.0)
    elif args.role == "relay":
        pub = session.declare_publisher("bench/b")

        def forward(sample):
            if args.mode != "handflow":
                pub.put(sample.payload, attachment=sample.attachment)
                return
            payload, att = wire.sample_parts(sample)
            msg = wire.unpack(payload, att)  # the runner's forwarding of an unchanged message
            payload, att = wire.repack(msg, payload) or wire.pack(msg)
            pub.put(pool.wrap(payload), attachment=att)

        session.declare_subscriber("bench/a", forward)
        time.sleep(args.seconds + args.warmup + 2)
    else:
        read = wire.unpack if args.mode == "handflow" else wire.peek

        def on(sample):
            h = read(*wire.sample_parts(sample))
            h = getattr(h, "header", h)
            rows.append((h.seq, time.time_ns() - h.stamp_ns))

        session.declare_subscriber("bench/b", on)
        time.sleep(args.seconds + args.warmup + 2)
    rss.append(_rss_kb())
    out = {"rows": rows, "cpu_s": time.process_time() - cpu0, "shm": pool.sent, "fallbacks": pool.fallbacks}
    Path(args.out).write_text(json.dumps({**out, "rss_kb": rss}))
    session.close()


def run_shm_chain(size: int, mode: str, rate: float, seconds: float) -> dict:
    """Three processes of ``_shm_role`` on one hub; latency stats, CPU of the chain, frames through shared memory."""
    from handflow.framework.network import sessions as transport
    from handflow.framework.network.settings import ZenohSettings

    hub_ep = transport.hub_endpoint_for()
    hub = transport.open_hub(ZenohSettings(shared_memory=mode != "tcp"), hub_ep)
    with tempfile.TemporaryDirectory() as tmp:
        outs = {r: Path(tmp) / f"{r}.json" for r in ("sub", "relay", "pub")}
        base = [sys.executable, __file__, "--_shm_role", "--hub", hub_ep, "--mode", mode, "--size", str(size)]
        base += ["--rate", str(rate), "--seconds", str(seconds)]
        procs = [subprocess.Popen([*base, "--role", r, "--out", str(o)]) for r, o in outs.items()]
        for p in procs:
            p.wait(timeout=seconds + 60)
        res = {r: json.loads(o.read_text()) for r, o in outs.items()}
    hub.close()
    rows = res["sub"]["rows"]
    stats = _stats([lat for _, lat in rows], [s for s, _ in rows], int(seconds * rate))
    busy = sum(r["cpu_s"] for r in res.values())
    return {
        **stats,
        "cpu_percent": 100 * busy / seconds,
        "via_shm": res["pub"]["shm"] + res["relay"]["shm"],
        "shm_fallbacks": res["pub"]["fallbacks"] + res["relay"]["fallbacks"],
        "rss_growth": {r: _growth(v["rss_kb"]) for r, v in res.items()},
        "rss_kb": {r: v["rss_kb"][-1] for r, v in res.items()},
    }


_RSS_PARTS = ("VmRSS", "RssAnon", "RssShmem")
"""The whole resident set, and its private (heap) and shared-memory (mapped pool pages) parts."""


def _rss_kb() -> dict[str, int]:
    status = Path("/proc/self/status").read_text()
    return {k: int(re.search(rf"{k}:\s+(\d+)", status).group(1)) for k in _RSS_PARTS}


def _growth(samples: list[dict[str, int]]) -> dict[str, float]:
    """Each RSS part's growth from the first sample (a quarter into the run) to the last."""
    return {k: samples[-1][k] / max(samples[0][k], 1) - 1 for k in _RSS_PARTS}


def run_shm(pairs: int, seconds: float, hd_seconds: float) -> dict:
    """The ``--shm`` sweep and the 1080p30 stream (module docstring)."""
    sweep: dict = {}
    for name, size in SWEEP.items():
        triples = [{m: run_shm_chain(size, m, IMAGE_RATE_HZ, seconds) for m in ("handflow", "shm", "tcp")}]
        triples += [
            {m: run_shm_chain(size, m, IMAGE_RATE_HZ, seconds) for m in ("handflow", "shm", "tcp")}
            for _ in range(pairs - 1)
        ]
        sweep[name] = {
            "runs": triples,
            **{
                f"{m}_p50_us": statistics.median(t[m]["median_us"] for t in triples) for m in ("handflow", "shm", "tcp")
            },
            "vs_bare_tcp": statistics.median(t["handflow"]["median_us"] / t["tcp"]["median_us"] for t in triples),
            "vs_bare_shm": statistics.median(t["handflow"]["median_us"] / t["shm"]["median_us"] for t in triples),
        }
        print(f"{name}: " + json.dumps({k: v for k, v in sweep[name].items() if k != "runs"}), file=sys.stderr)
    hd = run_shm_chain(SWEEP["1080p"], "handflow", IMAGE_RATE_HZ, hd_seconds)
    return {
        "sweep": sweep,
        "hd": hd,
        "shm.flat_ratio": sweep["4MiB"]["handflow_p50_us"] / sweep["4KiB"]["handflow_p50_us"],
        "shm.vs_bare_tcp": sweep["4MiB"]["vs_bare_tcp"],
        "shm.vs_bare_shm": sweep["4MiB"]["vs_bare_shm"],
        "shm.hd_lost": hd["lost"],
        "shm.hd_cpu_percent": hd["cpu_percent"],
    }


def run_raw(rate: float, seconds: float, hops: int, payload: str = "joints", mode: str = "handflow") -> dict:
    """Bare-Zenoh processes; ``mode`` 'handflow' encodes/decodes every message, 'raw' only moves bytes."""
    from handflow.framework.network import sessions as transport
    from handflow.framework.network.settings import ZenohSettings

    hub_ep = transport.hub_endpoint_for()
    hub = transport.open_hub(ZenohSettings(), hub_ep)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "rows.json"
        common = [
            sys.executable,
            __file__,
            "--_role",
            "--hub",
            hub_ep,
            "--rate",
            str(rate),
            "--seconds",
            str(seconds),
            "--warmup",
            "1.5",
            "--payload",
            payload,
            "--mode",
            mode,
        ]
        key = "bench/a" if hops == 1 else "bench/b"
        procs = [subprocess.Popen(common + ["--role", "sub", "--key", key, "--out", str(out)])]
        if hops == 2:
            procs.append(subprocess.Popen(common + ["--role", "relay"]))
        time.sleep(0.3)
        procs.append(subprocess.Popen(common + ["--role", "pub"]))
        for p in procs:
            p.wait(timeout=seconds + 30)
        rows = json.loads(out.read_text())
    hub.close()
    return _stats([r[1] for r in rows], [r[0] for r in rows], int(seconds * rate))


# ------------------------------------------------------------------------------------------------
# handflow graph
# ------------------------------------------------------------------------------------------------
def run_handflow(rate: float, seconds: float, hops: int, message: str = "array") -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        middle = (
            "  - id: scale\n    plugin: basic.select\n    inputs: {primary: source/out}\n"
            if message == "joint_state"
            else "  - id: scale\n    plugin: basic.transform\n    inputs: {in: source/out}\n"
        )
        middle = middle if hops == 2 else ""
        sink_src = "scale/out" if hops == 2 else "source/out"
        graph = tmp / "bench.yaml"
        graph.write_text(f"""name: bench
nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: noise, rate_hz: {rate}, width: {WIDTH}, message: {message}}}
{middle}  - id: sink
    plugin: basic.sink
    params: {{jsonl: sink.jsonl}}
    inputs: {{in: {sink_src}}}
""")
        summary = tmp / "summary.json"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "handflow.framework.cli",
                "--log-level",
                "WARNING",
                "run",
                str(graph),
                "--duration",
                str(seconds + 1.5),
                "--summary-json",
                str(summary),
            ],
            cwd=tmp,
            check=True,
        )
        rows = [json.loads(line) for line in (tmp / "sink.jsonl").read_text().splitlines()]
        gaps_upstream = sum(sum(u["gaps"].values()) for u in json.loads(summary.read_text()).values())
    # skip the first second (processes still connecting), like the raw set-up's warm-up
    t0 = rows[0]["arrival_ns"] + 1e9 if rows else 0
    rows = [r for r in rows if r["arrival_ns"] >= t0]
    stats = _stats([r["latency_ns"] for r in rows], [r["msg"]["header"]["seq"] for r in rows], None)
    stats["lost"] += gaps_upstream
    return stats


def image_codec_ms(repeats: int = 60) -> dict:
    """Median encode (``wire.pack``) and decode (``wire.unpack``, validated) of one 640×480 RGB frame, in ms."""
    return codec_ms(_image(0), repeats)


def joint_codec_us(repeats: int = 2000) -> dict:
    """The same for a 24-joint ``JointState`` (names and positions), in µs."""
    from handflow.framework.messages import JointState

    msg = JointState(names=[f"J{i}" for i in range(WIDTH)], positions=np.arange(float(WIDTH)))
    return {k.replace("_ms", "_us"): v * 1e3 if k != "bytes" else v for k, v in codec_ms(msg, repeats).items()}


def codec_ms(msg, repeats: int) -> dict:
    """Median encode and decode times (ms) of one message through the wire codec."""
    from handflow.framework import wire
    from handflow.framework.messages import Header

    msg.header = Header("bench", 1, time.time_ns())
    enc, dec = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        payload, att = wire.pack(msg)
        t1 = time.perf_counter()
        wire.unpack(payload, att)
        t2 = time.perf_counter()
        enc.append(t1 - t0)
        dec.append(t2 - t1)
    return {
        "encode_ms": 1e3 * statistics.median(enc),
        "decode_ms": 1e3 * statistics.median(dec),
        "total_ms": float(1e3 * statistics.median(np.add(enc, dec))),
        "bytes": len(payload),
    }


def recording_rate(frames: int = 300, repeats: int = 3) -> dict:
    """MB/s of ``McapWriter.write_encoded`` storing camera frames (CDR, zstd chunks) vs the bare mcap writer."""
    from mcap.writer import CompressionType, Writer

    from handflow.framework import wire
    from handflow.framework.files.mcap_writer import McapWriter

    payloads = [wire.pack(_image(i))[0] for i in range(8)]
    total_mb = frames * len(payloads[0]) / 1e6
    ours, bare = [], []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rec.mcap"
        for _ in range(repeats):
            t0 = time.perf_counter()
            with McapWriter(path) as w:
                for i in range(frames):
                    w.write_encoded("handflow/bench/cam/image", "handflow.Image", payloads[i % 8], i, i, i)
            ours.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            with open(path, "wb") as fh:
                bw = Writer(fh, chunk_size=McapWriter.CHUNK_SIZE, compression=CompressionType.ZSTD)
                bw.start(profile="ros2", library="bench")
                sid = bw.register_schema("sensor_msgs/msg/Image", "ros2msg", b"")
                cid = bw.register_channel("handflow/bench/cam/image", "cdr", sid)
                for i in range(frames):
                    bw.add_message(cid, i, payloads[i % 8], i, i)
                bw.finish()
            bare.append(time.perf_counter() - t0)
    return {
        "recording_mb_per_s": total_mb / statistics.median(ours),
        "bare_mcap_mb_per_s": total_mb / statistics.median(bare),
        "frames": frames,
        "frame_bytes": len(payloads[0]),
    }


def _paired(repeats: int, handflow, raw, first: tuple[dict, dict] | None = None) -> dict:
    """``repeats`` back-to-back (handflow, bare Zenoh) runs of one set-up (after ``first``, a pair
    already measured) and the median of their latency ratios: the machine's drift between runs
    moves both halves of a pair alike."""
    pairs = [first] if first else []
    pairs += [(handflow(), raw()) for _ in range(repeats)]
    ratios = [h["median_us"] / r["median_us"] for h, r in pairs]
    return {
        "pairs": [{"handflow_chain": h, "raw_chain": r, "ratio": q} for (h, r), q in zip(pairs, ratios)],
        "handflow_chain": pairs[-1][0],
        "raw_chain": pairs[-1][1],
        "ratio_median": statistics.median(ratios),
    }


def _stats(lat_ns: list[int], seqs: list[int], expected: int | None) -> dict:
    if not lat_ns:
        return {"median_us": float("nan"), "p99_us": float("nan"), "received": 0, "lost": expected or 0}
    seqs_arr = np.asarray(sorted(seqs))
    gaps = int(np.sum(np.diff(seqs_arr) - 1)) if len(seqs_arr) > 1 else 0
    lost = gaps if expected is None else expected - len(seqs)
    lat_us = np.asarray(lat_ns) / 1e3
    return {
        "median_us": float(np.median(lat_us)),
        "p99_us": float(np.percentile(lat_us, 99)),
        "received": len(seqs),
        "lost": int(lost),
    }


def _local(args: argparse.Namespace) -> dict:
    """The ``local`` section (``benchmarks/local_transport.py``), with this run's pairs and seconds."""
    from local_transport import run_local

    return run_local(args.pairs, min(args.seconds, 3.0), 60.0, args.seconds)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--rates", type=float, nargs="+", default=[100.0, 1000.0])
    ap.add_argument(
        "--pairs",
        type=int,
        default=3,
        help="back-to-back handflow/bare-Zenoh pairs of each chain at the top rate; the ratios are their median",
    )
    ap.add_argument(
        "--max-rates",
        type=float,
        nargs="+",
        default=[1000.0, 2000.0, 4000.0, 8000.0],
        help="rates tried for max_rate_hz_no_loss (handflow chain)",
    )
    ap.add_argument("--_role", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--role"), ap.add_argument("--hub"), ap.add_argument("--rate", type=float)
    ap.add_argument("--key"), ap.add_argument("--out"), ap.add_argument("--warmup", type=float, default=1.5)
    ap.add_argument("--payload", default="joints"), ap.add_argument("--mode", default="raw")
    ap.add_argument("--shm", action="store_true", help="only the shared-memory payload sweep and the 1080p30 stream")
    ap.add_argument("--hd-seconds", type=float, default=20.0, help="length of the 1080p30 stream (--shm)")
    ap.add_argument("--shm-soak", type=float, metavar="SECONDS", help="only the 1080p30 soak of that length")
    ap.add_argument(
        "--local", action="store_true", help="only the local-transport section (benchmarks/local_transport.py)"
    )
    ap.add_argument("--_shm_role", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--size", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._role:
        _role(args)
        return
    if args._shm_role:
        _shm_role(args)
        return
    if args.shm_soak:  # 1080p30 through three processes: shared-memory fallbacks and RSS growth
        res = run_shm_chain(SWEEP["1080p"], "handflow", IMAGE_RATE_HZ, args.shm_soak)
        print(json.dumps({k: v for k, v in res.items() if k not in ("p99_us",)}))
        return
    if args.shm:
        res = run_shm(args.pairs, args.seconds, args.hd_seconds)
        print(json.dumps(res) if args.json else json.dumps({k: v for k, v in res.items() if k.startswith("shm.")}))
        return
    if args.local:
        print(json.dumps(_local(args)))
        return
    results: dict = {"payload_floats": WIDTH, "seconds_per_run": args.seconds, "by_rate": {}}
    for rate in args.rates:
        key = str(int(rate))
        results["by_rate"][key] = {
            "handflow_chain": run_handflow(rate, args.seconds, 2),
            "handflow_single_hop": run_handflow(rate, args.seconds, 1),
            "raw_chain": run_raw(rate, args.seconds, 2, mode="raw"),
            "raw_single_hop": run_raw(rate, args.seconds, 1, mode="raw"),
        }
        if not args.json:
            print(f"{key} Hz: " + json.dumps(results["by_rate"][key]), file=sys.stderr)
    top = results["by_rate"][str(int(max(args.rates)))]
    results.update(
        {
            "median_latency_us": top["handflow_chain"]["median_us"],
            "p99_latency_us": top["handflow_chain"]["p99_us"],
            "raw_zenoh_median_latency_us": top["raw_single_hop"]["median_us"],
            "raw_zenoh_chain_median_latency_us": top["raw_chain"]["median_us"],
            "overhead_ratio_single_hop": top["handflow_single_hop"]["median_us"] / top["raw_single_hop"]["median_us"],
            "lost_at_top_rate": top["handflow_chain"]["lost"],
        }
    )
    top_rate = max(args.rates)
    arrays = _paired(
        args.pairs - 1,
        lambda: run_handflow(top_rate, args.seconds, 2),
        lambda: run_raw(top_rate, args.seconds, 2, mode="raw"),
        first=(top["handflow_chain"], top["raw_chain"]),
    )
    joint_state = _paired(
        args.pairs,
        lambda: run_handflow(top_rate, args.seconds, 2, "joint_state"),
        lambda: run_raw(top_rate, args.seconds, 2, "joint_state", mode="raw"),
    )
    results.update(
        {
            "chain_pairs": arrays,
            "overhead_ratio": arrays["ratio_median"],
            "joint_state": joint_state,
            "joint_state_overhead_ratio": joint_state["ratio_median"],
        }
    )
    image = {
        "handflow": run_raw(IMAGE_RATE_HZ, args.seconds, 1, "image", "handflow"),
        "raw": run_raw(IMAGE_RATE_HZ, args.seconds, 1, "image", "raw"),
    }
    codec = image_codec_ms()
    joints = joint_codec_us()
    rec = recording_rate()
    results.update(
        {
            "image": image,
            "image_overhead_ratio": image["handflow"]["median_us"] / image["raw"]["median_us"],
            "image_codec": codec,
            "image_codec_ms": codec["total_ms"],
            "joint_codec": joints,
            "recording": rec,
            "recording_mb_per_s": rec["recording_mb_per_s"],
        }
    )
    max_ok = 0.0
    for rate in args.max_rates:
        r = run_handflow(rate, min(args.seconds, 4.0), 2)
        ok = r["lost"] == 0 and r["received"] > 0.9 * rate * (min(args.seconds, 4.0) + 0.5 - 1.0)
        results.setdefault("max_rate_trials", {})[str(int(rate))] = {
            "lost": r["lost"],
            "received": r["received"],
            "ok": ok,
        }
        if not ok:
            break
        max_ok = rate
    results["max_rate_hz_no_loss"] = max_ok
    if args.json:
        results["local"] = _local(args)
        print(json.dumps(results))
    else:
        for k in (
            "median_latency_us",
            "p99_latency_us",
            "raw_zenoh_median_latency_us",
            "raw_zenoh_chain_median_latency_us",
            "overhead_ratio",
            "overhead_ratio_single_hop",
            "joint_state_overhead_ratio",
            "max_rate_hz_no_loss",
            "image_overhead_ratio",
            "image_codec_ms",
            "recording_mb_per_s",
        ):
            print(f"{k:38s} {results[k]:.3f}" if isinstance(results[k], float) else f"{k:38s} {results[k]}")


if __name__ == "__main__":
    main()
