"""Finding running graphs from outside: the launcher's run-files.

A graph's hub listens on a random loopback port, so ``handflow record / replay / monitor`` need to
learn it.  Each launcher writes ``<run dir>/<graph>.<pid>.json`` with its hub endpoint, pid and
graph file, and removes it on exit; a run-file whose pid is gone is stale and removed when found.
Run dir: ``$HANDFLOW_RUN_DIR``, else ``$XDG_RUNTIME_DIR/handflow/runs``, else
``~/.cache/handflow/runs``.  ``--connect ENDPOINT`` bypasses discovery (e.g. another machine).
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("handflow.discovery")


class DiscoveryError(LookupError):
    """No (or no unique) running graph matches; the text says what to pass instead."""


@dataclass(frozen=True)
class RunInfo:
    """What a launcher publishes about itself."""

    graph: str
    hub: str
    pid: int
    graph_file: str
    lockstep: bool
    started_ns: int


def run_dir() -> Path:
    env = os.environ.get("HANDFLOW_RUN_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    return Path(xdg) / "handflow" / "runs" if xdg else Path.home() / ".cache" / "handflow" / "runs"


def write_run_file(graph: str, hub: str, graph_file: str | Path, lockstep: bool = False) -> Path:
    """Announce a running launcher (atomic write); returns the file to remove on exit."""
    info = RunInfo(graph, hub, os.getpid(), str(graph_file), lockstep, time.time_ns())
    d = run_dir()
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"{graph}.{info.pid}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(asdict(info)))
    tmp.replace(path)
    return path


def remove_run_file(path: Path | None) -> None:
    if path is not None:
        path.unlink(missing_ok=True)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def live_runs() -> list[RunInfo]:
    """Running launchers, newest first (stale run-files are removed)."""
    runs = []
    d = run_dir()
    for f in d.glob("*.json") if d.is_dir() else []:
        try:
            info = RunInfo(**json.loads(f.read_text()))
        except (OSError, ValueError, TypeError):
            continue
        if _pid_alive(info.pid):
            runs.append(info)
        else:
            f.unlink(missing_ok=True)
    return sorted(runs, key=lambda r: r.started_ns, reverse=True)


def find_run(graph: str | None = None) -> RunInfo:
    """The running graph named ``graph`` (or the only running graph when None)."""
    runs = live_runs()
    if graph is not None:
        runs = [r for r in runs if r.graph == graph]
    if not runs:
        what = f"graph '{graph}'" if graph else "graph"
        raise DiscoveryError(
            f"no running {what} found in {run_dir()}; start it with `handflow run GRAPH.yaml`, "
            f"or pass --connect ENDPOINT (e.g. tcp/127.0.0.1:7447)"
        )
    names = sorted({r.graph for r in runs})
    if graph is None and len(names) > 1:
        raise DiscoveryError(f"several graphs are running ({', '.join(names)}); pass --graph NAME")
    if len(runs) > 1:
        log.info(
            "%d launchers of graph '%s' are running; joining the newest (pid %d)", len(runs), runs[0].graph, runs[0].pid
        )
    return runs[0]


def join(
    graph: str | None = None, connect: str | None = None, certs: str | None = None, name: str | None = None
) -> tuple[zenoh.Session, RunInfo | None]:
    """Open a Zenoh peer session on a running graph's network: ``connect`` if given, else via its run-file.

    A ``tls/`` endpoint needs ``certs`` (a ``handflow certs`` directory) and this machine's certificate
    ``name`` (docs/security.md).
    """
    import zenoh

    from .graph import ZenohSettings
    from .transport import open_node_session, open_tls_client

    run = None if connect else find_run(graph)
    endpoint = connect or run.hub
    if endpoint.startswith("tls/"):
        from .certs import CertError, check_host_files

        if not (certs and name):
            raise DiscoveryError(f"{endpoint} is a TLS endpoint: pass --certs DIR --cert-name NAME")
        try:
            files = check_host_files(Path(certs), name)
        except CertError as exc:
            raise DiscoveryError(str(exc)) from None
        try:
            return open_tls_client(endpoint, *files), run
        except zenoh.ZError as exc:
            raise DiscoveryError(
                f"could not join {endpoint} with certificate '{name}' ({str(exc).split(' at /')[0]}); check that the graph runs there and "
                f"that its CA signed {files[1]} (docs/security.md)"
            ) from None
    return open_node_session(ZenohSettings(), endpoint), run


def add_tls_arguments(parser) -> None:
    """``--certs DIR --cert-name NAME`` of commands that join a graph over TLS (docs/security.md)."""
    parser.add_argument("--certs", metavar="DIR", help="with a tls/ --connect endpoint: the `handflow certs` directory")
    parser.add_argument("--cert-name", metavar="NAME", help="with --certs: this machine's certificate name")
