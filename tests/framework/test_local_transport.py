"""Zero-copy messages between processes of one graph host through iceoryx2 (docs/shared_memory.md).

Real iceoryx2 ports in separate processes and real ``handflow run`` graphs.  Every test runs in a
private ``$TMPDIR``, which gives it its own iceoryx2 namespace (``local_transport.root_dir`` and
``prefix``), so "no file is left" is checked exactly while other handflow runs go on.
"""

from __future__ import annotations

import contextlib
import gc
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import zenoh
from hypothesis import given
from hypothesis import strategies as st

from handflow.framework import wire
from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.network import local_transport as lt
from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.runtime import local_routes
from handflow.framework.runtime.discovery import live_runs
from tests.framework._rec_helpers import REPO, ended_within, start, unique, wait_until, write_graph


@pytest.fixture
def namespace(tmp_path, monkeypatch):
    """A private iceoryx2 namespace for this test and the processes it starts (a short ``$TMPDIR``:
    iceoryx2's socket paths must fit the 108 bytes of a Unix socket address)."""
    tmp = Path(tempfile.mkdtemp(prefix="hf", dir="/tmp"))
    monkeypatch.setenv("TMPDIR", str(tmp))
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    monkeypatch.setattr("tempfile.tempdir", None)  # gettempdir() reads TMPDIR again
    yield tmp
    for f in Path("/dev/shm").glob(f"{lt.prefix()}*"):  # the namespace is this test's alone
        f.unlink(missing_ok=True)
    monkeypatch.setattr("tempfile.tempdir", None)
    shutil.rmtree(tmp, ignore_errors=True)


def _files() -> list[str]:
    shm = [f"/dev/shm/{f}" for f in os.listdir("/dev/shm") if f.startswith(lt.prefix())]
    return shm + ([str(lt.root_dir())] if lt.root_dir().exists() else [])


PUBLISHER = textwrap.dedent(
    """
    import sys
    import numpy as np
    from handflow.framework.network import local_transport as lt
    t = lt.LocalTransport(sys.argv[1], "test/publisher")
    pub = t.publisher("handflow/t/src/out")
    print("ready", flush=True)
    for i in range(int(sys.argv[2])):
        sys.stdin.readline()  # lock-step: the subscriber handled the message before
        assert pub.send(np.full(1000 + i % 50, i, np.int64).tobytes(), b"seq%d" % i) == 1
    sys.stdin.readline()
    t.close()
    """
)


def _publisher(run: str, count: int) -> subprocess.Popen:
    """A process publishing ``count`` messages, each once the test asks for it (:func:`_next`)."""
    proc = subprocess.Popen(
        [sys.executable, "-c", PUBLISHER, run, str(count)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
    return proc


def _next(proc: subprocess.Popen) -> None:
    proc.stdin.write("next\n")
    proc.stdin.flush()


def _end(proc: subprocess.Popen) -> None:
    """Let the publisher finish (its last read sees the end of its input) and wait for it."""
    proc.stdin.close()
    assert proc.wait(timeout=30) == 0, proc.stderr.read()


def test_views_keep_their_sample_alive_across_thousands_of_later_messages(namespace):
    transport = lt.LocalTransport("runviews", "test/subscriber")
    received: list[int] = []
    held: dict[int, np.ndarray] = {}

    def on_message(payload, att):
        seq = int(att[3:])
        received.append(seq)
        arr = np.frombuffer(payload, np.int64)
        if seq < 2 or seq % 250 == 0:  # the first two stay in place, later ones exceed BORROWED and are copies
            held[seq] = arr
        _next(pub)

    transport.subscribe("handflow/t/src/out", on_message)
    transport.start()
    pub = _publisher("runviews", 3000)
    try:
        time.sleep(0.5)  # the publisher connects to the subscriber
        _next(pub)
        wait_until(lambda: len(received) == 3000, timeout=60, what=f"3000 messages, got {len(received)}")
    finally:
        _end(pub)
    assert received == list(range(3000))  # each once, in order
    for seq, arr in held.items():
        assert arr.size == 1000 + seq % 50 and (arr == seq).all(), f"message {seq} was overwritten"
        assert not arr.flags.writeable
    in_place = [seq for seq, arr in held.items() if isinstance(arr.base, memoryview)]
    assert in_place[:2] == [0, 1] and transport.borrowed == lt.BORROWED - 1
    held.clear()
    gc.collect()
    assert transport.borrowed == 0  # every sample went back with its last view
    transport.close()


def test_a_view_outlives_the_closed_transport(namespace):
    transport = lt.LocalTransport("runclose", "test/subscriber")
    got = []
    transport.subscribe("handflow/t/src/out", lambda payload, att: got.append(np.frombuffer(payload, np.int64)))
    transport.start()
    pub = _publisher("runclose", 1)
    time.sleep(0.5)
    _next(pub)
    wait_until(lambda: got, timeout=30, what="a message")
    transport.close()
    _end(pub)
    assert (got[0] == 0).all() and got[0].size == 1000


class _FailingOnce:
    """A topic's real listener whose first wait fails, as an interrupted wait would."""

    def __init__(self, listener) -> None:
        self.listener, self.failed = listener, False

    def timed_wait(self, timeout):
        if not self.failed:
            self.failed = True
            raise RuntimeError("interrupted")
        return self.listener.timed_wait(timeout)

    def delete(self) -> None:
        self.listener.delete()


def test_a_failed_wait_does_not_end_the_topics_delivery(namespace, caplog):
    subscriber, got = lt.LocalTransport("runfail", "test/subscriber"), []
    subscriber.subscribe("handflow/t/src/out", lambda payload, att: got.append(bytes(payload)))
    topic = subscriber._topics["handflow/t/src/out"]
    topic.listener = _FailingOnce(topic.listener)
    subscriber.start()
    publishing = lt.LocalTransport("runfail", "test/publisher")
    publisher = publishing.publisher("handflow/t/src/out")
    wait_until(lambda: topic.listener.failed, timeout=10, what="the failed wait")
    for i in range(5):
        publisher.send(b"message %d" % i, b"att")
    wait_until(lambda: len(got) == 5, timeout=10, what=f"5 messages, got {len(got)}")
    assert got == [b"message %d" % i for i in range(5)]
    assert "RuntimeError: interrupted (1 time(s); retrying)" in caplog.text
    subscriber.close()
    publishing.close()


@given(st.binary(max_size=300), st.binary(max_size=80))
def test_frames_round_trip(payload, att):
    buf = bytearray(lt.frame_size(len(payload), len(att)))
    lt.write_frame(memoryview(buf), payload, att)
    off, got = lt.read_frame(memoryview(buf))
    assert got == att and bytes(buf[off:]) == payload and (off + 4) % 16 == 0


@given(st.binary(max_size=200))
def test_any_bytes_read_as_a_frame_or_raise_value_error(data):
    try:
        off, att = lt.read_frame(memoryview(data))
    except ValueError:
        return
    assert off <= len(data) and len(att) == int.from_bytes(data[:4], "little")


def test_unusable_iceoryx2_gives_a_reason_and_no_transport(monkeypatch):
    def missing():
        raise ImportError("No module named 'iceoryx2'")

    monkeypatch.setattr(lt, "_iox", missing)
    assert "ImportError" in (why := lt.prepare())
    assert "pip install iceoryx2" in lt.remedy(why) and "local: zenoh" in lt.remedy(why)  # what to do
    assert "/dev/shm" in lt.remedy("IOException: out of memory")
    assert lt.open_local("run1", "test") is None
    assert lt.remove_leftovers() == []


# -- graphs ---------------------------------------------------------------------------------------

WIDTH = 2048  # 16 KiB of float64 per message


def _graph(tmp_path: Path, name: str, local: str, port: int, record: Path | None = None) -> Path:
    rec = f"record: {{path: {record}}}\n" if record else ""
    return write_graph(
        tmp_path / f"{name}.yaml",
        name,
        f"""transport: {{local: {local}}}
zenoh: {{listen: [tcp/127.0.0.1:{port}]}}
{rec}nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: noise, rate_hz: 50, width: {WIDTH}, seed: 3}}
  - id: scale
    plugin: basic.transform
    params: {{gain: 1.0}}
    inputs: {{in: source/out}}
  - id: sink
    plugin: basic.sink
    inputs: {{in: scale/out}}
""",
    )


def _peer(port: int) -> zenoh.Session:
    """A remote-style reader: its own Zenoh session, shared memory off."""
    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/shared_memory/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    return zenoh.open(conf)


class _Health:
    """The nodes' heartbeats read over Zenoh (no data topic subscribed, so no Zenoh match)."""

    def __init__(self, session: zenoh.Session, graph: str) -> None:
        self.counters: dict[str, dict[str, float]] = {}
        self.pids: dict[str, int] = {}
        self._sub = session.declare_subscriber(f"handflow/{graph}/*/_health", self._on)

    def _on(self, sample) -> None:
        status = wire.unpack(*wire.sample_parts(sample))
        self.counters[status.header.source] = dict(status.counters)
        self.pids[status.header.source] = int(status.text.split()[1])  # "pid N"

    def get(self, node: str, key: str) -> float | None:
        return self.counters.get(node, {}).get(key)


@dataclass
class _Run:
    """A graph run by :func:`_running`; ``returncode`` and the launcher's ``err`` once it ended."""

    name: str
    session: zenoh.Session
    health: _Health | None = None
    returncode: int | None = None
    err: str = ""


@contextmanager
def _running(tmp_path: Path, prefix: str, seconds: int, again: tuple[str, int] | None = None):
    """The iceoryx2 graph running for at most ``seconds``, read by a remote-style peer, once its sink handles
    messages and both publishers have reported a path; stopped with Ctrl-C at the end of the block.
    ``again``: the name and hub port of a graph run before (the same iceoryx2 services)."""
    name, port = again or (unique(prefix), free_tcp_port())
    proc = start("run", str(_graph(tmp_path, name, "iceoryx2", port)), "--duration", str(seconds))
    run = _Run(name, _peer(port))
    try:
        run.health = _Health(run.session, name)
        wait_until(lambda: (run.health.get("sink", "handled.in") or 0) > 20, timeout=60, what="the sink handling")
        # each node reports on its own clock: a publisher's first heartbeat after it published may come later
        wait_until(lambda: all(run.health.get(n, "path.out") for n in ("source", "scale")), timeout=10, what="paths")
        yield run
    except AssertionError as exc:  # the graph's log says why
        run.err = ended_within(proc, 30.0, tmp_path, "the launcher", sig=signal.SIGINT)
        raise AssertionError(f"{exc}\nthe launcher's log:\n{run.err[-4000:]}") from None
    finally:
        if proc.returncode is None:
            run.err = ended_within(proc, 30.0, tmp_path, "the launcher", sig=signal.SIGINT)
        run.returncode = proc.returncode
        run.session.close()


def test_local_subscribers_take_iceoryx2_and_zenoh_readers_get_the_same_bytes(tmp_path, namespace):
    with _running(tmp_path, "local", 30) as launched:
        name, session, health = launched.name, launched.session, launched.health
        # no Zenoh reader of the data topics: they travel through iceoryx2 only
        assert health.get("source", "path.out") == lt.LOCAL and health.get("scale", "path.out") == lt.LOCAL
        run = next(r for r in live_runs() if r.graph == name)
        local = lt.LocalTransport(local_routes.run_of(run.hub), "test/local-reader")  # a subscriber on this host
        local_got: dict[int, bytes] = {}
        local.subscribe(
            f"handflow/{name}/scale/out",
            lambda payload, att: local_got.__setitem__(wire.parse_attachment(att)[2], bytes(payload)),
        )
        local.start()
        zenoh_got: dict[int, bytes] = {}
        sub = session.declare_subscriber(
            f"handflow/{name}/scale/out",
            lambda s: zenoh_got.__setitem__(wire.parse_attachment(s.attachment.to_bytes())[2], s.payload.to_bytes()),
        )
        wait_until(lambda: len(zenoh_got) >= 20, timeout=30, what="20 messages over Zenoh")
        path = lambda node: health.get(node, "path.out")  # noqa: E731 - of the latest heartbeat (every 0.5 s)
        wait_until(lambda: path("scale") == lt.LOCAL | lt.ZENOH, timeout=5, what="scale/out over both paths")
        assert path("source") == lt.LOCAL  # its topic still has no Zenoh reader
        sub.undeclare()
        wait_until(lambda: path("scale") == lt.LOCAL, timeout=5, what="scale/out over iceoryx2 alone again")
        local.close()  # before the launcher ends, which removes the files once no node is alive
    assert launched.returncode == 0, launched.err
    # each message once: the sink handled exactly what scale published, without gaps
    assert health.get("sink", "handled.in") == health.get("scale", "published.out")
    assert health.get("sink", "gaps.in") == 0 and health.get("scale", "gaps.in") == 0
    common = sorted(set(local_got) & set(zenoh_got))
    assert len(common) >= 15 and all(local_got[q] == zenoh_got[q] and len(zenoh_got[q]) > WIDTH * 8 for q in common)
    assert "iceoryx2 is not usable" not in launched.err
    assert _files() == [], "iceoryx2 files left after the launcher ended"


def _record(tmp_path: Path, local: str) -> dict[str, dict[int, bytes]]:
    """``{node: {seq: CDR payload}}`` of the recorded ``source/out`` and ``scale/out`` of a 4 s run."""
    name, port = unique(f"rec_{local}"), free_tcp_port()
    out = tmp_path / f"{name}.mcap"
    proc = start("run", str(_graph(tmp_path, name, local, port, out)), "--duration", "4")
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    return {
        n: {m.sequence: m.data for m in iter_recording(out, [f"handflow/{name}/{n}/out"])} for n in ("source", "scale")
    }


def test_recordings_with_and_without_iceoryx2_are_byte_identical_but_for_the_stamp(tmp_path, namespace):
    with_local, without = _record(tmp_path, "iceoryx2"), _record(tmp_path, "zenoh")
    a, b = with_local["source"], without["source"]
    both = sorted(set(a) & set(b))
    assert len(both) >= 100
    for s in both:
        assert len(a[s]) > WIDTH * 8 and a[s][:4] + a[s][12:] == b[s][:4] + b[s][12:]  # bytes 4..12: the stamp
    # what scale (gain 1) received in place and republished is what the source published, stamp and all
    sources = {body[4:] for body in a.values()}
    assert len(with_local["scale"]) >= 100 and all(body[4:] in sources for body in with_local["scale"].values())


def test_without_iceoryx2_one_notice_and_the_graph_runs_over_zenoh(tmp_path, namespace):
    fake = tmp_path / "fake"
    (fake / "iceoryx2").mkdir(parents=True)
    (fake / "iceoryx2" / "__init__.py").write_text("raise ImportError('iceoryx2 withheld by the test')\n")
    env = {**os.environ, "PYTHONPATH": f"{fake}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    name, port = unique("noiox"), free_tcp_port()
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(_graph(tmp_path, name, "iceoryx2", port))]
        + ["--duration", "2"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("iceoryx2 is not usable here") == 1, proc.stderr
    received = [line for line in proc.stderr.splitlines() if "received" in line and "sink" in line]
    assert received and int(received[-1].split("received ")[1].split()[0]) >= 50


def test_killed_processes_are_replaced_and_leave_no_file(tmp_path, namespace):
    with _running(tmp_path, "kill", 60) as run:
        health = run.health
        for node in ("sink", "source"):  # a subscriber (which holds samples while it handles them), a publisher
            pid = health.pids[node]
            os.kill(pid, signal.SIGKILL)
            wait_until(lambda n=node, p=pid: health.pids[n] != p, timeout=60, what=f"{node} restarted")
        before = health.get("sink", "handled.in")
        wait_until(lambda: health.get("sink", "handled.in") > before + 20, timeout=60, what="the graph to recover")
    assert run.returncode == 0, run.err
    assert _files() == [], "iceoryx2 files left after the launcher ended"


def test_segments_are_readable_by_the_same_user_only(namespace):
    """docs/security.md, "Shared memory on a shared host"."""
    pub_side, sub_side = lt.LocalTransport("runperm", "test/pub"), lt.LocalTransport("runperm", "test/sub")
    got = []
    sub_side.subscribe("handflow/t/src/out", lambda payload, att: got.append(bytes(payload)))
    sub_side.start()
    publisher = pub_side.publisher("handflow/t/src/out")
    wait_until(lambda: publisher.send(b"secret", b"att") == 1 and got, timeout=10, what="a message")
    modes = {f: os.stat(f).st_mode & 0o777 for f in _files() if f.startswith("/dev/shm/")}
    data = {f: m for f, m in modes.items() if not f.endswith(".global_mgmt")}  # 16 bytes, no content
    assert data and set(data.values()) == {0o600}, modes
    assert os.stat(lt.root_dir()).st_mode & 0o777 == 0o700
    sub_side.close()
    pub_side.close()
    assert lt.remove_leftovers() and _files() == []


def test_an_allocated_image_is_published_in_place_and_zenoh_readers_get_its_bytes(namespace):
    """``ctx.allocate`` on the local transport: the pixels are written into the sample once; a Zenoh
    reader gets the same payload bytes, and the subscriber's decoded image views the sample."""
    from handflow.framework.messages import Header, Image
    from handflow.framework.runtime.local_routes import LOCAL, ZENOH, OutputPort

    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    port = free_tcp_port()
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    pub_session, reader = zenoh.open(conf), _peer(port)
    pub_side, sub_side = lt.LocalTransport("runimg", "test/pub"), lt.LocalTransport("runimg", "test/sub")
    local_got, zenoh_got, paths = [], [], []
    try:
        sub_side.subscribe(
            "handflow/t/cam/image", lambda payload, att: local_got.append((wire.unpack(payload, att), bytes(payload)))
        )
        sub_side.start()
        reader.declare_subscriber("handflow/t/cam/image", lambda s: zenoh_got.append(s.payload.to_bytes()))
        key = "handflow/t/cam/image"
        out = OutputPort(pub_session.declare_publisher(key), pub_side.publisher(key))
        wait_until(lambda: out.zenoh.matching_status.matching, timeout=10, what="the Zenoh reader")
        for seq in range(1, 4):
            pixels = out.allocate(640 * 480 * 3)
            assert pixels.flags.writeable
            pixels[:] = seq
            msg = Image(width=640, height=480, encoding="rgb8", step=640 * 3, data=pixels)
            msg.header = Header("cam", seq, 1000 + seq)
            paths.append(out.publish(msg, None, lambda payload: payload)[0])
        wait_until(
            lambda: len(local_got) == 3 and len(zenoh_got) == 3,
            timeout=30,
            what=f"three images each way, got {len(local_got)} in place and {len(zenoh_got)} over Zenoh",
        )
    finally:
        sub_side.close()
        pub_side.close()
        reader.close()
        pub_session.close()
    assert paths == [LOCAL | ZENOH] * 3
    for seq, ((img, payload), zbytes) in enumerate(zip(local_got, zenoh_got), 1):
        expected = Image(width=640, height=480, encoding="rgb8", step=640 * 3, data=bytes([seq]) * (640 * 480 * 3))
        expected.header = Header("cam", seq, 1000 + seq)
        assert payload == zbytes == wire.pack(expected)[0]  # the encoder's bytes, the pixels never copied
        assert (img.to_array() == seq).all()
    # the subscriber holds the first two in place (read-only views of their samples); holding
    # BORROWED - 1 already, it got the third as a copy
    assert [type(img.data) for img, _ in local_got] == [np.ndarray, np.ndarray, bytes]
    assert not any(img.data.flags.writeable for img, _ in local_got[:2])


def _interrupted_start(graph: Path, how: signal.Signals, after_s: float) -> str:
    """Start ``handflow run GRAPH`` in its own process group and send ``how`` to the whole group ``after_s``
    after its first node process started (start-up still going on); the launcher's stderr so far."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph)],
        cwd=REPO,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    lines = []
    try:
        for line in proc.stderr:
            lines.append(line)
            if "started " in line:
                break
        time.sleep(after_s)
        os.killpg(proc.pid, how)
        lines += proc.stderr.readlines()
        proc.wait(timeout=60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # a Ctrl-C'd launcher's nodes are gone with it; none is left
        proc.wait(timeout=60)
    return "".join(lines)


@pytest.mark.slow
def test_launchers_killed_during_start_up_never_switch_the_local_transport_off(tmp_path, namespace):
    """Ctrl-C (SIGINT) and ``kill -9`` of the launcher's process group during start-up, 10 times, half each
    (docs/shared_memory.md, "Processes that die"); the next run uses iceoryx2 with no file removed by hand."""
    name, port = unique("interrupted"), free_tcp_port()
    graph = _graph(tmp_path, name, "iceoryx2", port)
    notices = []
    for i in range(10):
        how = signal.SIGINT if i % 2 else signal.SIGKILL
        err = _interrupted_start(graph, how, after_s=0.1 * (i // 2))  # while its nodes open their ports
        notices += [line for line in err.splitlines() if "not usable" in line]
    with _running(tmp_path, "after", 30, again=(name, port)) as run:  # the same iceoryx2 services
        assert run.health.get("source", "path.out") == lt.LOCAL  # the monitor's path column: iceoryx2
        assert run.health.get("scale", "path.out") == lt.LOCAL
    assert run.returncode == 0, run.err
    assert "not usable" not in run.err, run.err
    assert notices == []
    assert _files() == [], "iceoryx2 files left after the last launcher ended"
