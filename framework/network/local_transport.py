"""Zero-copy messages between the node processes of one graph host through iceoryx2 (docs/shared_memory.md).

One :class:`LocalTransport` per node process.  A topic is an iceoryx2 publish-subscribe service of
``uint8`` slices plus an event service of the same name, both named after the launcher's run
(:func:`service_name`), so two runs of a graph on one machine never share a topic.  A published
sample holds one frame::

    uint32 len(attachment)   attachment (the handflow wire attachment)   padding   CDR payload

The padding puts the payload 4 bytes before a 16-byte boundary, so the CDR body after its 4-byte
encapsulation header is 16-byte aligned and decoded arrays are aligned numpy views.  The publisher
copies the encoded message once into a loaned sample and notifies the topic's listeners; a
subscriber process wakes on the notification (a thread per subscribed topic blocked in its listener's
wait, no polling: an iceoryx2 ``WaitSet`` over all topics in one thread took twice as long) and hands
the callback a read-only ``memoryview`` straight into the sample.  The sample is given back to the
publisher when the last view of it (the memoryview, numpy arrays decoded from it) is gone.  A
subscriber may hold at most :data:`BORROWED` samples: once a process holds ``BORROWED - 1``, the
next message is copied out and its sample given back at once, so a node that keeps many messages
never blocks the transport.

A subscriber whose buffer of :data:`BUFFER` samples is full loses the oldest (iceoryx2's safe
overflow): the runner counts it as a sequence gap.  Files live under :func:`root_dir` and carry
:func:`prefix` in ``/dev/shm``.  A launcher calls :func:`prepare` at its start (reclaims what dead
processes left, iceoryx2's dead-node cleanup, and says whether iceoryx2 is usable here) and
:func:`remove_leftovers` at its end (deletes the files once no node of the namespace is alive).
When iceoryx2 cannot be used (not installed, no ``/dev/shm``, a sandbox), the launcher logs one
notice and :func:`open_local` returns ``None`` in every node process: the caller uses Zenoh.
"""

from __future__ import annotations

import ctypes
import logging
import os
import shutil
import struct
import tempfile
import threading
import weakref
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger("handflow.local")

BUFFER = 256
"""Messages a subscriber buffers before it loses the oldest (drop-oldest, counted as a gap): a node
process that the machine's load or a long tick holds up catches up afterwards, as over Zenoh."""
FRAME_BUFFER = 32
"""The same for bulky topics (images): about a second at 30 fps."""
BORROWED = 3
"""Samples a subscriber process may hold at once (views kept by its nodes); beyond, messages are copied."""
MAX_SUBSCRIBERS = 8
"""Subscriber processes per topic."""
SAMPLES = BUFFER + 2 * BORROWED
"""Samples a publisher owns (iceoryx2 would preallocate ``MAX_SUBSCRIBERS × (BUFFER + BORROWED)`` and more),
each as large as its largest message.  Freed samples are reused first, so while subscribers keep up
only a few are ever touched; a subscriber that falls behind pins up to ``BUFFER + BORROWED - 1``.
When subscribers hold every sample, a message cannot be loaned: it is not sent locally
(:attr:`LocalPublisher.unsent`, a gap for the subscribers) and the publisher never waits."""
FRAME_SAMPLES = FRAME_BUFFER + 16
"""The same for bulky topics, whose samples are megabytes each: at most 48 × the largest frame."""
INITIAL_BYTES = 4096
"""A publisher's first sample size; its segment grows by powers of two for larger messages."""
POLL_S = 0.2
"""How often the waiting thread looks whether it should stop (wake-ups for messages are events)."""
ZENOH = 1
"""A message went over Zenoh (the ``path.<port>`` heartbeat counter is a sum of these flags)."""
LOCAL = 2
"""A message went to at least one local subscriber through iceoryx2."""
PATH_NAMES = {0: "-", ZENOH: "zenoh", LOCAL: "iceoryx2", ZENOH | LOCAL: "iceoryx2+zenoh"}
LOAN_RESERVE = 1024
"""Bytes before the data of a loaned array (:meth:`LocalPublisher.loan`): frame header, attachment
and the CDR of the message's other fields."""
MAX_LOANS = 3
"""Arrays a publisher lends at once; beyond, ``ctx.allocate`` returns an ordinary array."""
_HEAD = struct.Struct("<II")  # attachment length, payload offset
Callback = Callable[[memoryview | bytes, bytes], None]


def _iox() -> Any:
    import iceoryx2

    return iceoryx2


def root_dir() -> Path:
    """iceoryx2's directory for this user's handflow nodes and services (mode 0700), in ``$TMPDIR``."""
    return Path(tempfile.gettempdir()) / f"handflow-iox2-{os.getuid()}"


def preload() -> None:
    """Import iceoryx2 ahead (the zygote, before it forks node processes: it starts no thread)."""
    try:
        _iox()
    except ImportError:
        pass


def prefix() -> str:
    """The prefix of the files that go with :func:`root_dir` in ``/dev/shm`` (one namespace per user and ``$TMPDIR``)."""
    return f"hf{os.getuid()}x{zlib.crc32(str(root_dir()).encode()):08x}_"


def _config(iox: Any) -> Any:
    root = root_dir()
    root.mkdir(mode=0o700, exist_ok=True)
    cfg = iox.config.default()
    cfg.global_cfg.prefix = iox.FileName.new(prefix())
    cfg.global_cfg.root_path = iox.Path.new(f"{root}/")
    return cfg


def service_name(run: str, topic: str) -> str:
    """The iceoryx2 service of a topic key in the launcher run ``run`` (its hub port)."""
    return f"{run}/{topic}"


def payload_offset(att_len: int) -> int:
    """Where :func:`write_frame` puts the CDR payload after an attachment of ``att_len`` bytes (module doc)."""
    return -(-(_HEAD.size + att_len + 4) // 16) * 16 - 4


def write_head(view: memoryview, att: bytes, offset: int) -> None:
    """The frame header and attachment of a frame whose payload starts at ``offset``."""
    _HEAD.pack_into(view, 0, len(att), offset)
    view[_HEAD.size : _HEAD.size + len(att)] = att


def write_frame(view: memoryview, payload: bytes | bytearray | memoryview, att: bytes) -> None:
    """Lay out one message in a sample of ``frame_size(len(payload), len(att))`` bytes (module doc)."""
    write_head(view, att, payload_offset(len(att)))
    view[payload_offset(len(att)) :] = payload


def frame_size(payload_len: int, att_len: int) -> int:
    return payload_offset(att_len) + payload_len


def read_frame(view: memoryview) -> tuple[int, bytes]:
    """``(payload offset, attachment)`` of a frame; ``ValueError`` when the bytes are no frame."""
    if len(view) < _HEAD.size:
        raise ValueError(f"a frame needs at least {_HEAD.size} bytes, got {len(view)}")
    n, off = _HEAD.unpack_from(view, 0)
    if not _HEAD.size + n <= off <= len(view):
        raise ValueError(f"a frame of {len(view)} bytes cannot hold an attachment of {n} bytes and a payload at {off}")
    return off, bytes(view[_HEAD.size : _HEAD.size + n])


def open_local(run: str, name: str) -> LocalTransport | None:
    """This process's transport for the launcher run ``run``; ``None`` when iceoryx2 is unusable (the
    launcher gave the notice, :func:`prepare`)."""
    try:
        return LocalTransport(run, name)
    except Exception as exc:  # ImportError, a missing /dev/shm, a sandbox: whatever iceoryx2 raises
        log.debug("iceoryx2 is not usable here (%s: %s); local topics use Zenoh", type(exc).__name__, exc)
        return None


class LocalPublisher:
    """One output port's iceoryx2 publisher and notifier."""

    def __init__(self, publisher: Any, notifier: Any, loan_error: type[Exception]) -> None:
        self._pub, self._notifier, self._loan_error = publisher, notifier, loan_error
        self.unsent = 0  # messages no sample could be loaned for (every sample held, SAMPLES)
        self._loans: dict[int, tuple[Any, memoryview, weakref.ref]] = {}  # id(array) → sample, its view, array

    def loan(self, nbytes: int) -> np.ndarray | None:
        """A writable ``uint8`` array of ``nbytes`` inside a loaned sample (``ctx.allocate``), or ``None``
        when :data:`MAX_LOANS` are out or no sample is free.  Published with :meth:`send_loaned`; an
        array dropped unpublished gives its sample back."""
        if len(self._loans) >= MAX_LOANS:
            return None
        try:
            sample = self._pub.loan_slice_uninit(LOAN_RESERVE + nbytes)
        except self._loan_error:
            return None
        view = sample.payload().as_memory_view().cast("B")
        arr = np.frombuffer(view, np.uint8, count=nbytes, offset=LOAN_RESERVE)
        key = id(arr)
        self._loans[key] = (sample, view, weakref.ref(arr))
        weakref.finalize(arr, self._loans.pop, key, None)
        return arr

    def lent(self, data: Any) -> bool:
        """Whether ``data`` is an array of :meth:`loan` not yet sent."""
        loan = self._loans.get(id(data))
        return loan is not None and loan[2]() is data

    def send_loaned(
        self, data: np.ndarray, prefix: bytes, att: bytes, copy_out: bool
    ) -> tuple[int, bytes | None] | None:
        """Send the sample holding ``data`` with the CDR ``prefix`` (the message up to ``data``) before
        it: no copy of the data.  Returns the subscribers reached and, with ``copy_out``, the payload's
        bytes (for Zenoh); ``None`` when ``prefix`` and ``att`` do not fit :data:`LOAN_RESERVE`."""
        sample, view, _ = self._loans[id(data)]
        offset = LOAN_RESERVE - len(prefix)
        if offset < _HEAD.size + len(att):
            return None
        del self._loans[id(data)]
        write_head(view, att, offset)
        view[offset:LOAN_RESERVE] = prefix
        payload = bytes(view[offset:]) if copy_out else None
        receivers = sample.assume_init().send()
        if receivers:
            self._notifier.notify()
        return receivers, payload

    def send(self, payload: bytes | bytearray | memoryview, att: bytes) -> int:
        """Copy one message into a loaned sample and send it; returns how many subscribers received it."""
        try:
            sample = self._pub.loan_slice_uninit(frame_size(len(payload), len(att)))
        except self._loan_error as exc:
            self.unsent += 1
            if self.unsent == 1 or self.unsent % 1000 == 0:
                log.warning("no free sample (%s): %d message(s) not sent through iceoryx2", exc, self.unsent)
            return 0
        write_frame(sample.payload().as_memory_view().cast("B"), payload, att)
        receivers = sample.assume_init().send()
        if receivers:
            self._notifier.notify()
        return receivers


class _Topic:
    """A subscribed topic: its iceoryx2 subscriber, listener and the callbacks of this process."""

    def __init__(self, name: str, subscriber: Any, listener: Any) -> None:
        self.name, self.subscriber, self.listener = name, subscriber, listener
        self.callbacks: list[Callback] = []


class LocalTransport:
    """A node process's iceoryx2 node: publishers, subscriptions and the thread that delivers messages."""

    def __init__(self, run: str, name: str) -> None:
        iox = self._iox = _iox()
        iox.set_log_level(iox.LogLevel.Error)
        self.run = run
        self._node = (
            iox.NodeBuilder.new()
            .config(_config(iox))
            .name(iox.NodeName.new(name[:100]))
            .signal_handling_mode(iox.SignalHandlingMode.Disabled)
            .create(iox.ServiceType.Ipc)
        )
        self._topics: dict[str, _Topic] = {}
        self._pubs: list[Any] = []
        self._borrowed = 0  # samples of this process still referenced by a view
        self._count_lock = threading.Lock()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._probe()

    def _probe(self) -> None:
        """Create and release a publisher of an ordinary topic's size: raises where its shared-memory
        segment cannot be made (a full ``/dev/shm``, a file-size limit), so that the process takes the
        Zenoh path (:func:`open_local`) instead of failing at its first output port."""
        self.publisher(f"_probe/{os.getpid()}")
        for port in self._pubs.pop():  # the probe's publisher and notifier
            port.delete()

    def _services(self, topic: str) -> tuple[Any, Any]:
        iox = self._iox
        name = iox.ServiceName.new(service_name(self.run, topic))
        pubsub = (
            self._node.service_builder(name)
            .publish_subscribe(iox.Slice[ctypes.c_uint8])
            .payload_alignment(iox.Alignment.new(16))
            .enable_safe_overflow(True)
            .history_size(0)
            .subscriber_max_buffer_size(BUFFER)
            .subscriber_max_borrowed_samples(BORROWED)
            .max_subscribers(MAX_SUBSCRIBERS)
            .max_publishers(2)  # a restarted node's publisher while the dead one is cleaned up
            .open_or_create()
        )
        event = self._node.service_builder(name).event().open_or_create()
        return pubsub, event

    def publisher(self, topic: str, bulky: bool = False) -> LocalPublisher:
        """The topic's publisher; ``bulky`` (images) owns :data:`FRAME_SAMPLES` samples, else :data:`SAMPLES`."""
        pubsub, event = self._services(topic)
        pub = (
            pubsub.publisher_builder()
            .initial_max_slice_len(INITIAL_BYTES)
            .allocation_strategy(self._iox.AllocationStrategy.PowerOfTwo)
            .override_sample_preallocation(FRAME_SAMPLES if bulky else SAMPLES)
            .max_loaned_samples(MAX_LOANS + 1)
            .create()
        )
        notifier = event.notifier_builder().create()
        self._pubs.append((pub, notifier))
        return LocalPublisher(pub, notifier, self._iox.LoanError)

    def subscribe(self, topic: str, callback: Callback, bulky: bool = False) -> None:
        """Call ``callback(payload, attachment)`` for each message of ``topic`` (from :meth:`start` on);
        ``bulky`` (images) buffers :data:`FRAME_BUFFER` messages, else :data:`BUFFER`."""
        if topic not in self._topics:
            pubsub, event = self._services(topic)
            subscriber = pubsub.subscriber_builder().buffer_size(FRAME_BUFFER if bulky else BUFFER).create()
            self._topics[topic] = _Topic(topic, subscriber, event.listener_builder().create())
        self._topics[topic].callbacks.append(callback)

    def start(self) -> None:
        """Start delivering the subscribed topics (a thread per topic waits for its events)."""
        if self._threads:
            return
        for topic in self._topics.values():
            thread = threading.Thread(
                target=self._wait, args=(topic,), name=f"handflow-local {topic.name}", daemon=True
            )
            thread.start()
            self._threads.append(thread)

    def _wait(self, topic: _Topic) -> None:
        timeout = self._iox.Duration.from_secs_f64(POLL_S)
        failures = 0
        while not self._stop.is_set():
            try:
                topic.listener.timed_wait(timeout)
                self._drain(topic)
            except Exception as exc:  # a failed wait or receive must not end the topic's delivery
                failures += 1
                if failures == 1 or failures % 1000 == 0:
                    log.warning("%s: %s: %s (%d time(s); retrying)", topic.name, type(exc).__name__, exc, failures)
                self._stop.wait(POLL_S)

    def _drain(self, topic: _Topic) -> None:
        while not self._stop.is_set():
            sample = topic.subscriber.receive()
            if sample is None:
                return
            try:
                payload, att = self._frame(sample)
            except ValueError as exc:
                log.warning("dropped a malformed sample on %s: %s", topic.name, exc)
                continue
            finally:
                del sample  # only the views keep it from here on: BORROWED counts on that
            for callback in topic.callbacks:
                callback(payload, att)
            del payload

    def _frame(self, sample: Any) -> tuple[memoryview | bytes, bytes]:
        """The frame's payload (a read-only view keeping ``sample`` alive, or a copy) and attachment."""
        slice_ = sample.payload()
        raw = (ctypes.c_uint8 * slice_.len()).from_address(slice_.as_ptr())
        off, att = read_frame(memoryview(raw).cast("B"))
        with self._count_lock:
            keep = self._borrowed < BORROWED - 1
            self._borrowed += keep
        if not keep:
            return bytes(memoryview(raw)[off:]), att
        raw.sample = sample  # the view's owner chain: numpy array → memoryview → raw → sample
        weakref.finalize(raw, self._given_back)
        return memoryview(raw).cast("B").toreadonly()[off:], att

    def _given_back(self) -> None:
        with self._count_lock:
            self._borrowed -= 1

    @property
    def borrowed(self) -> int:
        """Samples this process holds through views right now."""
        return self._borrowed

    def stop(self) -> None:
        """Stop delivering (views still held stay valid until dropped)."""
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=5 * POLL_S)

    def close(self) -> None:
        """:meth:`stop`, then release every port and the node, which removes their files (a process
        that ends without this, e.g. killed, leaves them to the dead-node cleanup)."""
        self.stop()
        ports = [p for t in self._topics.values() for p in (t.subscriber, t.listener)]
        ports += [p for pair in self._pubs for p in pair]
        for port in ports:
            port.delete()
        self._topics.clear()
        self._pubs.clear()
        self._node = None  # dropping the last reference releases the node


def _reclaim_dead_nodes() -> int:
    """Remove what dead handflow nodes of this namespace left; returns how many nodes are alive.

    A node killed while it was being created or cleaned up (a launcher's process group stopped during
    start-up) can be one whose cleanup iceoryx2 refuses (``NodeCleanupFailure``, e.g.
    ``ResourcesAlreadyCleanedUp``) and lists as dead for ever: its files are removed here instead."""
    iox = _iox()
    iox.set_log_level(iox.LogLevel.Error)
    alive = 0
    for state in iox.Node.list(iox.ServiceType.Ipc, _config(iox)):
        if isinstance(state, iox.NodeState.Dead):
            try:
                state._0.try_remove_stale_resources()
            except Exception as exc:  # iceoryx2's NodeCleanupFailure
                log.debug("dead iceoryx2 node %s: %s; removing its files", state._0.id.value, exc)
                _remove_node_files(state._0.id.value)
        alive += isinstance(state, iox.NodeState.Alive)
    return alive


def _remove_node_files(node_id: object) -> None:
    nodes = root_dir() / "nodes"
    shutil.rmtree(nodes / str(node_id), ignore_errors=True)
    for f in nodes.glob(f"{prefix()}{node_id}.*"):
        f.unlink(missing_ok=True)


def _remove_namespace() -> list[str]:
    """Delete every file of this namespace (``/dev/shm/<prefix>*`` and :func:`root_dir`); returns them."""
    removed = [str(p) for p in Path("/dev/shm").glob(f"{prefix()}*")]
    for p in removed:
        Path(p).unlink(missing_ok=True)
    if root_dir().exists():
        shutil.rmtree(root_dir(), ignore_errors=True)
        removed.append(str(root_dir()))
    return removed


def prepare() -> str | None:
    """At a launcher's start: reclaim dead nodes' resources and check that a transport opens; ``None`` when
    iceoryx2 is usable, else why not (:func:`remedy` says what to do).  When it does not open and no
    handflow node of the namespace is alive, the namespace is started afresh and tried once more."""
    try:
        alive = _reclaim_dead_nodes()
        try:
            LocalTransport("probe", "handflow/probe").close()
        except Exception:
            if alive:
                raise
            log.debug("iceoryx2 did not open; removed %s", _remove_namespace())
            LocalTransport("probe", "handflow/probe").close()
    except Exception as exc:  # ImportError, a missing /dev/shm, a sandbox: whatever iceoryx2 raises
        return f"{type(exc).__name__}: {exc}"
    return None


def remedy(why: str) -> str:
    """What to do when :func:`prepare` found iceoryx2 unusable for the reason ``why``."""
    if why.startswith("ImportError"):
        return "To use it: pip install iceoryx2 (or set 'transport: {local: zenoh}' to silence this)."
    return (
        f"To use it: check that /dev/shm is writable and has room and that $TMPDIR ({tempfile.gettempdir()}) is "
        f"shorter than ~60 characters; its files ({root_dir()}, /dev/shm/{prefix()}*) are removed when a run "
        "ends and no handflow node of this user is alive. Or set 'transport: {local: zenoh}' (docs/shared_memory.md)."
    )


def remove_leftovers() -> list[str]:
    """Reclaim dead nodes' resources and, when no handflow node of this namespace is alive, delete its
    files (``/dev/shm/<prefix>*`` and :func:`root_dir`); returns what was deleted."""
    try:
        if _reclaim_dead_nodes():
            return []
    except Exception as exc:  # not usable: nothing of ours can be there
        log.debug("no iceoryx2 cleanup: %s", exc)
        return []
    return _remove_namespace()
