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

REACH_S = 3.0  # how long a reader waits for a link to the hub, then again for the hub's graphs


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
    usrpwd: bool = False  # the hub asks every peer for a user and password


def run_dir() -> Path:
    env = os.environ.get("HANDFLOW_RUN_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    return Path(xdg) / "handflow" / "runs" if xdg else Path.home() / ".cache" / "handflow" / "runs"


def write_run_file(graph: str, hub: str, graph_file: str | Path, lockstep: bool = False, usrpwd: bool = False) -> Path:
    """Announce a running launcher (atomic write); returns the file to remove on exit."""
    info = RunInfo(graph, hub, os.getpid(), str(graph_file), lockstep, time.time_ns(), usrpwd)
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
        raise DiscoveryError(f"several graphs are running ({', '.join(names)}); name one of them (--graph NAME)")
    if len(runs) > 1:
        log.info(
            "%d launchers of graph '%s' are running; joining the newest (pid %d)", len(runs), runs[0].graph, runs[0].pid
        )
    return runs[0]


def join(
    graph: str | None = None,
    connect: str | None = None,
    certs: str | None = None,
    name: str | None = None,
    credentials: str | None = None,
    user: str | None = None,
) -> tuple[zenoh.Session, RunInfo | None]:
    """Open a Zenoh session on a running graph's network: ``connect`` if given, else via its run-file.

    A ``tls/`` endpoint needs ``certs`` (a ``handflow certs`` directory) and this machine's certificate
    ``name``; a graph with ``zenoh.usrpwd`` needs ``credentials`` (a file of ``user:password`` lines)
    and ``user`` when it holds several (docs/security.md).  Such sessions are clients of the hub.
    """
    import zenoh

    from ..network.sessions import open_client, open_node_session
    from ..network.settings import ZenohSettings

    run = None if connect else find_run(graph)
    endpoint = connect or run.hub
    certificate = _certificate(endpoint, certs, name)
    login = _login(run, credentials, user)
    if certificate is None and login is None:
        return open_node_session(ZenohSettings(), endpoint), run
    try:
        return open_client(endpoint, certificate, login), run
    except zenoh.ZError as exc:
        who, checks = [], ["--connect (that the graph runs there)"]
        if certificate is not None:
            who.append(f"certificate '{name}'")
            checks.append(f"--certs/--cert-name (that the hub's CA signed {certificate[1]})")
        if login is not None:
            who.append(f"user '{login['user']}'")
            checks.append("--credentials/--user (that the graph's credentials file holds this user and password)")
        raise DiscoveryError(
            f"could not join {endpoint} with {' and '.join(who)} ({str(exc).split(' at /')[0]}); "
            f"check {' and '.join(checks)} (docs/security.md)"
        ) from None


def join_graphs(
    graph: str | None = None,
    connect: str | None = None,
    certs: str | None = None,
    name: str | None = None,
    credentials: str | None = None,
    user: str | None = None,
) -> tuple[zenoh.Session, RunInfo | None, dict[str, dict]]:
    """:func:`join` as a reader, and the graphs whose hubs answer there (only ``graph`` when given).

    The graph of a run-file is the one joined; ``--connect`` lists every graph on that hub
    (:mod:`handflow.framework.network.hub_info`).  Reaching no hub, or no graph, is a :class:`DiscoveryError`
    naming the option to change: never an empty view.
    """
    session, run = join(graph, connect, certs, name, credentials, user)
    try:
        return session, run, _graphs_reached(session, connect or run.hub, run.graph if run else graph, name)
    except BaseException:
        session.close()
        raise


def _graphs_reached(session: zenoh.Session, endpoint: str, graph: str | None, cert_name: str | None) -> dict:
    from ..network.hub_info import graphs_on

    deadline = time.monotonic() + REACH_S
    while not (session.info.routers_zid() or session.info.peers_zid()):
        if time.monotonic() > deadline:
            raise DiscoveryError(
                f"nothing answered at {endpoint} within {REACH_S:.0f}s: check --connect (the address and port "
                f"the graph listens on, and the scheme: a TLS hub needs tls/ADDR:PORT with --certs DIR --cert-name NAME)"
            )
        time.sleep(0.05)
    found: dict[str, dict] = {}
    deadline = time.monotonic() + REACH_S  # declarations arrive after the link, other peers' hubs after gossip
    while (graph is None or graph not in found) and time.monotonic() < deadline:
        found |= graphs_on(session, timeout_s=1.0)
        time.sleep(0.2)
    if graph is not None and graph in found:
        return {graph: found[graph]}
    if graph is not None and found:
        raise DiscoveryError(f"{endpoint} runs no graph '{graph}' (it runs {', '.join(sorted(found))}); check --graph")
    if not found:
        check = (
            f"is certificate '{cert_name}' listed in the graph's 'zenoh.tls.readers'? If not, add it there or "
            f"pass --cert-name of a listed one (docs/security.md)"
            if cert_name
            else "check --connect"
        )
        raise DiscoveryError(f"{endpoint} answered, but no handflow graph answered through it; {check}")
    return found


def _certificate(endpoint: str, certs: str | None, name: str | None) -> tuple[Path, Path, Path] | None:
    """(CA, certificate, key) for a ``tls/`` endpoint, checked first; None for other endpoints."""
    if not endpoint.startswith("tls/"):
        return None
    from ..security.certs import CertError, check_host_files

    if not (certs and name):
        raise DiscoveryError(f"{endpoint} is a TLS endpoint: pass --certs DIR --cert-name NAME")
    try:
        return check_host_files(Path(certs), name)
    except CertError as exc:
        raise DiscoveryError(str(exc)) from None


def _login(run: RunInfo | None, credentials: str | None, user: str | None) -> dict[str, str] | None:
    """``usrpwd`` login from a credentials file; a local graph that needs one and got none is an error."""
    from ..security.credentials import CredentialsError, read_credentials, usrpwd_settings

    if credentials is None:
        if user is not None:
            raise DiscoveryError("--user needs --credentials FILE (its password is read from that file)")
        if run is not None and run.usrpwd:
            raise DiscoveryError(
                f"graph '{run.graph}' asks for a user and password: pass --credentials FILE [--user NAME]"
            )
        return None
    try:
        creds = read_credentials(credentials, warn_shared=True)
        return usrpwd_settings(creds, creds.login(user)[0])
    except CredentialsError as exc:
        raise DiscoveryError(str(exc)) from None


def add_auth_arguments(parser) -> None:
    """``--certs DIR --cert-name NAME`` and ``--credentials FILE --user NAME`` of commands that join a
    secure graph (docs/security.md)."""
    parser.add_argument("--certs", metavar="DIR", help="with a tls/ --connect endpoint: the `handflow certs` directory")
    parser.add_argument("--cert-name", metavar="NAME", help="with --certs: this machine's certificate name")
    parser.add_argument(
        "--credentials", metavar="FILE", help="for a graph with 'zenoh.usrpwd': a file of user:password lines"
    )
    parser.add_argument("--user", metavar="NAME", help="with --credentials: which user (default: the only one)")
