"""``handflow run G.yaml --watch``: restart the nodes whose plugin source or graph entry changed, while
the rest of the graph keeps running (docs/tuning.md, "Editing a running graph").

A thread reads the graph file and the source files of the plugins the launcher runs
(:func:`.plugin_sources.plugin_files`) every ``POLL_S`` and compares their contents (a save that
changes nothing changes nothing); it acts once they have stayed the same for one more poll, so an
editor's save in several steps is taken whole.  The edit is first checked in a process of its own
(:func:`main`: forked from the zygote with the edited modules forgotten, or a new interpreter): the
graph text validates with the plugins' current code, the nodes' inputs checked as at start.  A
failed check logs every problem as ``file:line: message`` and changes nothing; so does an edit of a
top-level key other than ``nodes``, ``description`` and ``external``, which takes effect only when the
graph is run again.  Otherwise :meth:`.launcher.Launcher.reload` restarts, in the supervising thread,
the nodes whose entry changed, whose plugin's files changed (every node of that plugin) and the
nodes sharing their process (``group:``), starts added nodes and stops removed ones; the line
``reloaded: ... (FILE changed) in X s`` is logged once they run.  Changed files are compared with the
running version: an edit reverted before it was taken is no change, and one reverted after (a refused
edit undone) is logged as ``FILE back to the running version``.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import subprocess
import sys
import threading
import time
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING

from ..files.yaml import line_of, parse
from ..graphs.model import Graph, GraphError, GraphSpec, load_graph
from .plugin_sources import drop_bytecode, forget, plugin_files

if TYPE_CHECKING:
    from .supervisor import WatchHost

log = logging.getLogger("handflow.watch")

POLL_S = 0.1  # a change is taken 0.1-0.2 s after the save (files are stat-ed, read only when changed)
CHECK_TIMEOUT_S = 60.0  # importing the graph's plugins takes this long at most
READY_TIMEOUT_S = 60.0  # a restarted node reports ready within this
LIVE_KEYS = frozenset({"nodes", "description", "external"})  # top-level keys an edit may change while running
CHECK = "handflow.framework.runtime.watch"


def _shown(path: Path) -> str:
    """``path`` relative to the current directory when under it (as the user named it), else in full."""
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


class Watcher:
    """Watches the files of a running graph and reloads what changed (see the module docstring)."""

    def __init__(self, launcher: WatchHost, text: str) -> None:
        self.launcher = launcher
        self.path = launcher.graph.path
        self.text = text  # the graph file's running version
        self._digests: dict[Path, tuple[tuple[int, int], str]] = {}
        self.sources = self._sources(launcher.graph)
        # the files' running versions: the graph file's as the launcher read it (an edit since then is one)
        self.running = {**self._contents(), self.path: hashlib.sha1(text.encode()).hexdigest()}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="handflow-watch", daemon=True)
        self._thread.start()

    def _sources(self, graph: Graph) -> dict[str, frozenset[Path]]:
        """Plugin name → its source files, for the plugins of the nodes this launcher runs."""
        nids = [nid for unit in self.launcher.units for nid in unit.node_ids]
        return {graph.nodes[nid].spec.plugin: plugin_files(graph.nodes[nid].cls) for nid in nids}

    def _digest(self, path: Path) -> str | None:
        """A hash of the file's content (read again only when its mtime or size changed); None if unreadable."""
        try:
            st = path.stat()
            stamp = (st.st_mtime_ns, st.st_size)
            if (known := self._digests.get(path)) is not None and known[0] == stamp:
                return known[1]
            digest = hashlib.sha1(path.read_bytes()).hexdigest()
        except OSError:
            return None
        self._digests[path] = (stamp, digest)
        return digest

    def _contents(self) -> dict[Path, str | None]:
        files = {self.path, *(f for files in self.sources.values() for f in files)}
        return {path: self._digest(path) for path in sorted(files)}

    def _run(self) -> None:
        last, pending = self.running, None
        while not self._stop.wait(POLL_S):
            now = self._contents()
            if now == last:
                pending = None
            elif now != pending:
                pending = now  # taken once it stays so for one more poll
            else:
                reverted = [path for path, digest in now.items() if digest != last.get(path)]
                last, pending = now, None
                changed = [path for path, digest in now.items() if digest != self.running.get(path)]
                if changed:
                    self._reload(changed, now)
                else:  # e.g. a refused edit undone: the error logged before is no longer the files' state
                    log.info(
                        "%s back to the running version: nothing to reload", ", ".join(_shown(p) for p in reverted)
                    )

    def _reload(self, changed: list[Path], now: dict[Path, str | None]) -> None:
        t0 = time.monotonic()
        why = f"{', '.join(_shown(p) for p in changed)} changed"
        code = {p for p in changed if p != self.path}
        for path in code:
            drop_bytecode(path)
        edited_plugins = {name for name, files in self.sources.items() if files & code}
        edited = set().union(*(self.sources[name] for name in edited_plugins))
        try:
            text = self.path.read_text()
        except OSError as exc:
            return self._refuse(why, f"{_shown(self.path)}:1: cannot read the graph file: {exc.strerror}")
        problems = self._check(text, edited)
        if problems:
            return self._refuse(why, problems)
        forget(edited)  # the launcher's own copy of the graph: the plugins' new classes and params
        try:
            new = load_graph(self.path, text=text)
        except GraphError as exc:  # it passed the check: a plugin whose import differs from one try to the next
            return self._refuse(why, str(exc))
        old = self.launcher.graph
        if fixed := _fixed_keys(old.spec, new.spec, text, self.path):
            return self._refuse(why, "\n".join(fixed))
        if all(rn.spec.host != self.launcher.host for rn in new.nodes.values()):
            where = f" for host '{self.launcher.host}'" if self.launcher.host else ""
            return self._refuse(why, f"{_shown(self.path)}:1: the edit leaves no node to run{where}")
        touched = {
            nid
            for nid, rn in new.nodes.items()
            if nid not in old.nodes or rn.spec != old.nodes[nid].spec or rn.spec.plugin in edited_plugins
        }
        done = self._apply(new, text, touched, edited, why)
        if done is None:
            return None
        self.text, self.sources = text, self._sources(new)
        self.running = {**self._contents(), **now}  # files it watches from now on: as they are
        took = time.monotonic() - t0
        log.info("reloaded: %s (%s) in %.2fs", "; ".join(done) or "no node changed", why, took)
        return None

    def _apply(self, new: Graph, text: str, touched: set[str], edited: set[Path], why: str) -> list[str] | None:
        """Let the supervising thread reload ``new`` and wait until the nodes it started report ready
        (None: the launcher stopped meanwhile)."""
        launcher, result, applied = self.launcher, {}, threading.Event()

        def reload() -> None:
            try:
                launcher.edited |= edited
                result["done"] = launcher.reload(new, text, touched, why)
                result["units"] = [u for u in launcher.units if not touched.isdisjoint(u.node_ids)]
            finally:
                applied.set()

        launcher.call_soon(reload)
        while not applied.wait(0.05):
            if self._stop.is_set():
                return None
        deadline = time.monotonic() + READY_TIMEOUT_S
        while not all(launcher.ready(u) for u in result.get("units", [])) and time.monotonic() < deadline:
            if self._stop.wait(0.02):
                return None
        return result.get("done")

    def _check(self, text: str, edited: Collection[Path]) -> str | None:
        """None if ``text`` loads with the plugins' current code, else the problems, one ``file:line: message``
        a line (as the check printed them)."""
        launcher = self.launcher
        candidate = launcher.state_dir / "graph-edit.yaml"
        candidate.write_text(text)
        args = [
            _shown(self.path),
            "--graph-text",
            str(candidate),
            *(["--host", launcher.host] if launcher.host else []),
        ]
        proc = launcher.start_process(CHECK, args, "the check of the edit", edited)
        output: list[str] = []
        reader = threading.Thread(target=lambda: output.append(proc.stderr.read()), daemon=True)
        reader.start()
        try:
            code = proc.wait(timeout=CHECK_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            return (
                f"{_shown(self.path)}:1: loading the graph's plugins did not finish within {CHECK_TIMEOUT_S:.0f}s "
                "(a plugin module that hangs when imported?)"
            )
        reader.join(timeout=1.0)
        if code == 0:
            return None
        return "".join(output).strip() or f"the check of the edit failed with exit code {code}"

    def _refuse(self, why: str, problems: str) -> None:
        log.error(
            "%s, not taken:\n%s\nthe running nodes keep their version; fix the problems above and save again",
            why,
            problems,
        )

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=CHECK_TIMEOUT_S)


def _fixed_keys(old: GraphSpec, new: GraphSpec, text: str, path: Path) -> list[str]:
    """``file:line: ...`` for each top-level key the edit changed that cannot change while the graph runs."""
    keys = [key for key in GraphSpec.model_fields if key not in LIVE_KEYS and getattr(old, key) != getattr(new, key)]
    if not keys:
        return []
    _, lines = parse(text)
    return [
        f"{_shown(path)}:{line_of(lines, (key,))}: '{key}' changed: it takes effect only when the graph starts; "
        "stop the graph and run it again"
        for key in keys
    ]


def main(argv: list[str] | None = None, parent: int | None = None) -> int:
    """Check an edit, in a process of its own: exit 0 if the graph text loads and validates with the
    plugins' current code, else 2 with every problem on stderr as ``file:line: message``."""
    ap = argparse.ArgumentParser(prog=f"python -m {CHECK}", description="Check an edit of a running graph.")
    ap.add_argument("graph")
    ap.add_argument("--graph-text", type=Path, required=True, help="the edited content of the graph file")
    ap.add_argument("--host", help="check the inputs of the nodes of this host")
    args = ap.parse_args(argv)
    try:
        load_graph(args.graph, preflight=True, host=args.host, text=args.graph_text.read_text())
    except GraphError as exc:
        print(exc, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
