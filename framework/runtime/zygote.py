"""Fork server for node processes: import a graph's plugins once, fork every node process from it.

Started by the launcher before its own Zenoh session exists (``python -m handflow.framework.runtime.zygote
GRAPH FD``); it loads the graph (which imports every plugin module the graph names, with their numpy,
scikit-learn, numba and pybullet), then forks one child per spawn request.  A child starts its own
session (setsid), takes the stderr pipe the launcher passed with the request, the launcher's working
directory and environment, and runs :func:`handflow.framework.runtime.runner.main` as a node process started
with ``python -m handflow.framework.runtime.runner`` would (or the ``main`` of another module the request
names, e.g. the check of an edit by ``handflow run --watch``).  A request may name source files
edited since the zygote imported them: the child forgets their modules first, so it imports their
current code (:func:`.plugin_sources.forget`, docs/tuning.md "Editing a running graph").  The zygote reports each child's pid and, when it
exits, its exit status (negative: killed by that signal, as :class:`subprocess.Popen` reports it).
It exits when the launcher's end of the socket closes (the launcher stopped or was killed); its
children then see their parent gone and stop (docs/architecture.md, "Process start-up").

Requests and replies are JSON lines on a Unix stream socket pair; a spawn request carries the
child's stderr pipe as ``SCM_RIGHTS``.
"""

from __future__ import annotations

import atexit
import importlib
import io
import json
import os
import queue
import select
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Collection, Iterator
from contextlib import contextmanager

from .plugin_sources import forget
from .wakeup import wakeup_queue

RUNNER = "handflow.framework.runtime.runner"
MAX_REQUEST = 1 << 16
REAP_S = 0.05
SPAWN_TIMEOUT_S = 60.0  # the zygote answers a spawn request once it has imported the graph's plugins
CLOSE_WAIT_S = 2.0  # at the close, how long the zygote may take to exit before it is killed


def _exit_status(status: int) -> int:
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _child(sock: socket.socket, request: dict, stderr_fd: int, zygote: int) -> None:
    """In the forked child: become a node process (stopping with the zygote) and never return."""
    code = 1
    try:
        sock.close()
        os.setsid()
        module = request.get("module", RUNNER)
        _set_title(module, request["argv"])
        os.dup2(stderr_fd, 2)
        os.close(stderr_fd)
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGCHLD):
            signal.signal(sig, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})  # a stop sent meanwhile ends it now
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        if "numpy" in sys.modules:  # each node process draws its own unseeded randomness, as a fresh one would
            sys.modules["numpy"].random.seed()
        forget(request.get("forget", ()))
        sys.argv = [module, *request["argv"]]
        code = importlib.import_module(module).main(request["argv"], parent=zygote)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:
        traceback.print_exc()
    finally:
        atexit._run_exitfuncs()  # what a fresh interpreter runs at exit (its imports registered them, or the zygote's)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:
                pass
        os._exit(code)


def _preload(graph_source: str) -> None:
    """Import what the graph's nodes import; a graph that does not load is the launcher's to report."""
    from ..graphs import model as graph
    from ..network import local_transport
    from . import runner  # noqa: F401  (the node runtime itself)

    local_transport.preload()

    try:
        graph.load_graph(graph_source)
    except Exception:
        pass


def _set_title(module: str, argv: list[str]) -> None:
    """Show the node process in ``ps`` as the command that would start it afresh."""
    try:
        import setproctitle
    except ImportError:  # pragma: no cover (a declared dependency)
        return
    setproctitle.setproctitle(" ".join([sys.executable, "-m", module, *argv]))


def serve(sock: socket.socket) -> None:
    """Answer spawn requests and report exits until the launcher's end closes."""
    buffer, fds = b"", []
    while True:
        readable, _, _ = select.select([sock], [], [], REAP_S)
        if readable:
            try:
                data, new_fds, _, _ = socket.recv_fds(sock, MAX_REQUEST, 4)
            except OSError:
                data, new_fds = b"", []
            if not data:  # the launcher is gone
                return
            buffer += data
            fds += new_fds
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            stderr_fd = fds.pop(0)
            zygote = os.getpid()
            # the launcher's SIGTERM may reach the child before it has left the zygote's SIG_IGN: blocked over
            # the fork, it waits in the child until its own disposition is set, instead of being lost
            blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
            pid = os.fork()
            if pid == 0:
                _child(sock, json.loads(line), stderr_fd, zygote)
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
            os.close(stderr_fd)
            if not _reply(sock, {"spawned": pid}):
                return
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                break
            if pid == 0:
                break
            if not _reply(sock, {"exited": pid, "code": _exit_status(status)}):
                return


def _reply(sock: socket.socket, body: dict) -> bool:
    try:
        sock.sendall(json.dumps(body).encode() + b"\n")
    except OSError:  # the launcher is gone
        return False
    return True


def start_unless_disabled(graph_source: str | os.PathLike) -> Zygote | None:
    """A started :class:`Zygote`, or None when ``HANDFLOW_ZYGOTE=0`` asks for fresh interpreters."""
    return Zygote.start(graph_source) if os.environ.get("HANDFLOW_ZYGOTE", "1") != "0" else None


@contextmanager
def zygote_while(graph_source: str | os.PathLike) -> Iterator[Zygote | None]:
    """:func:`start_unless_disabled` for a command's block, closed at its end: the nodes have stopped
    (or never started), so it has nothing left to fork.  A launcher given it may close it first; closing
    twice is harmless."""
    zygote = start_unless_disabled(graph_source)
    try:
        yield zygote
    finally:
        if zygote is not None:
            zygote.close()


def _alive(pid: int) -> bool:
    """Whether a process that is not our child runs (a zombie nobody reaps counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except FileNotFoundError:
        return False
    except OSError:  # no /proc (macOS): ask the kernel
        pass
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


class ForkedProcess:
    """A node process forked by the zygote, with the part of :class:`subprocess.Popen`'s interface the
    launcher uses (``pid``, ``stderr``, ``poll``, ``wait``, ``send_signal``, ``kill``, ``returncode``)."""

    def __init__(self, zygote: Zygote, pid: int, stderr: io.TextIOBase, args: list[str]) -> None:
        self.zygote = zygote
        self.pid = pid
        self.stderr = stderr
        self.args = args
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self.zygote.exit_code(self.pid)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise subprocess.TimeoutExpired(self.args, timeout)
            self.zygote.wait_for_exit(min(REAP_S, left) if left is not None else REAP_S)
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


class Zygote:
    """The launcher's end of the fork server; :meth:`start` it before any Zenoh session exists."""

    def __init__(self, proc: subprocess.Popen, sock: socket.socket) -> None:
        self.proc = proc
        self.sock = sock
        self._spawned = wakeup_queue()
        self._exits: dict[int, int] = {}
        self._changed = threading.Condition()
        self.closed = False
        self.usable = True
        self._spawning = threading.Lock()  # one request at a time: replies come in the order of the requests
        threading.Thread(target=self._read, name="zygote-replies", daemon=True).start()

    @classmethod
    def start(cls, graph_source: str | os.PathLike) -> Zygote:
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        proc = subprocess.Popen(
            [sys.executable, "-m", "handflow.framework.runtime.zygote", str(graph_source), str(theirs.fileno())],
            pass_fds=[theirs.fileno()],
            stdin=subprocess.DEVNULL,
        )
        theirs.close()
        return cls(proc, ours)

    def _read(self) -> None:
        try:
            for line in self.sock.makefile("rb"):
                self._on_reply(json.loads(line))
        except (OSError, ValueError):
            pass
        with self._changed:
            self.closed = True
            self._changed.notify_all()
        self._spawned.put(None)

    def _on_reply(self, reply: dict) -> None:
        if "spawned" in reply:
            self._spawned.put(reply["spawned"])
            return
        with self._changed:
            self._exits[reply["exited"]] = reply["code"]
            self._changed.notify_all()

    def spawn(self, argv: list[str], module: str = RUNNER, edited: Collection[str] = ()) -> ForkedProcess | None:
        """Fork a process running ``module.main(argv)`` (a node process by default) that imports the
        ``edited`` source files afresh; None if the zygote cannot (then start one as a new interpreter)."""
        if self.closed or not self.usable:
            return None
        read_fd, write_fd = os.pipe()
        request = {
            "argv": argv,
            "module": module,
            "forget": sorted(edited),
            "cwd": os.getcwd(),
            "env": dict(os.environ),
        }
        try:
            with self._spawning:
                socket.send_fds(self.sock, [json.dumps(request).encode() + b"\n"], [write_fd])
                pid = self._spawned.get(timeout=SPAWN_TIMEOUT_S)
        except (OSError, queue.Empty):
            pid = None
        finally:
            os.close(write_fd)
        if pid is None:
            self.usable = False  # a late reply would be taken for the next request's
            os.close(read_fd)
            return None
        stderr = open(read_fd, encoding="utf-8", errors="replace", buffering=1)
        return ForkedProcess(self, pid, stderr, [module, *argv])

    def exit_code(self, pid: int) -> int | None:
        """The child's exit status once it has exited; a child whose zygote is gone is asked directly."""
        with self._changed:
            if pid in self._exits:
                return self._exits[pid]
            if not self.closed:
                return None
        return None if _alive(pid) else -signal.SIGKILL  # its status went with the zygote

    def wait_for_exit(self, timeout: float) -> None:
        with self._changed:
            self._changed.wait(timeout)

    def close(self) -> None:
        """End the zygote (its remaining children, if any, then stop on their own)."""
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()
        try:  # it ends within a poll of the close; one still importing the graph's plugins is killed
            self.proc.wait(timeout=CLOSE_WAIT_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def main(argv: list[str] | None = None) -> int:
    graph_source, fd = (argv or sys.argv[1:])[:2]
    # Ctrl-C and a SIGTERM for the launcher's process group are the launcher's to handle: it stops the
    # nodes in order, then closes the socket, and that ends the zygote.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sock = socket.socket(fileno=int(fd))
    _preload(graph_source)
    serve(sock)
    return 0


if __name__ == "__main__":
    sys.exit(main())
