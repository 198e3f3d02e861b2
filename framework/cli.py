"""The ``handflow`` command: sub-commands are entry points of group ``handflow.commands``.

Each entry point names ``register(parser)``, which adds its arguments to its sub-parser and sets
``func=run`` where ``run(args) -> int`` is the exit code.  Dotted names nest (``evaluate.grasping``
→ ``handflow evaluate grasping``), so families add commands without touching the framework.
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import logging
import os
import re
import select
import signal
import sys
from importlib.metadata import EntryPoint
from pathlib import Path

from .files.provenance import installed_version
from .registry import command_entries


def _requested_path(argv: list[str]) -> tuple[str, ...]:
    """The positional words of ``argv`` before its first option-like word after the command."""
    words, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--log-level":
            skip = True
        elif arg.startswith("-"):
            if words:
                break
        else:
            words.append(arg)
    return tuple(words)


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The full parser; only the entry points on the requested command's path are imported (fast start)."""
    requested = _requested_path(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="handflow",
        description="Streams glove, camera and simulator data through "
        "plugins over Zenoh; learns, drives and recognises motions with structured manifolds.",
    )
    parser.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    parser.add_argument(
        "--version",
        action="version",
        version=f"%(prog)s {installed_version()}",
        help="print the installed handflow distribution's version and exit",
    )
    subparsers: dict[tuple[str, ...], argparse._SubParsersAction] = {
        (): parser.add_subparsers(dest="command", metavar="COMMAND")
    }
    entries = command_entries()
    listed = lambda path: requested == path[: len(requested)]  # noqa: E731 - whose help line a listing shows
    for ep in entries:
        path = tuple(ep.name.split("."))
        for depth in range(1, len(path)):
            prefix = path[:depth]
            if prefix not in subparsers:
                grp = subparsers[prefix[:-1]].add_parser(
                    prefix[-1], help=_group_summary(prefix, entries) if listed(prefix[:-1]) else None
                )
                subparsers[prefix] = grp.add_subparsers(dest=f"command_{depth}", metavar="WHAT")
        parent = subparsers[path[:-1]]
        if requested[: len(path)] != path:
            parent.add_parser(path[-1], help=summary(ep) if listed(path[:-1]) else None)
            continue
        try:
            register = ep.load()
        except Exception as exc:  # a broken family must not take the whole CLI down
            broken = parent.add_parser(path[-1], help=f"(unavailable: {exc})")
            broken.add_argument(
                "ignored", nargs=argparse.REMAINDER, help=argparse.SUPPRESS
            )  # say why, whatever follows
            broken.set_defaults(func=lambda args, exc=exc, name=ep.name: _unavailable(name, exc))
            continue
        doc = (register.__doc__ or "").strip().splitlines()
        sub = parent.add_parser(path[-1], help=doc[0] if doc else None, description=" ".join(doc) or None)
        register(sub)
    return parser


def _source_file(module: str) -> Path | None:
    """The source file of ``module``, found without importing it or a package not yet imported (a family's
    ``__init__`` may import numpy and more): the spec of its longest prefix whose parent is imported, then
    the folders below."""
    parts = module.split(".")
    depth = 1
    while depth < len(parts) and ".".join(parts[:depth]) in sys.modules:
        depth += 1
    try:
        spec = importlib.util.find_spec(".".join(parts[:depth]))
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    if depth == len(parts):
        return Path(spec.origin) if spec.origin and spec.origin.endswith(".py") else None
    for folder in spec.submodule_search_locations or []:
        base = Path(folder).joinpath(*parts[depth:])
        for candidate in (base.with_suffix(".py"), base / "__init__.py"):
            if candidate.is_file():
                return candidate
    return None


def summary(ep: EntryPoint) -> str | None:
    """The first line of the docstring of a command's ``register`` function, read from its source without
    importing it (``handflow --help`` stays fast; a name re-exported with ``from .module import name`` is
    followed); None if not found."""
    module, _, attr = ep.value.partition(":")
    return _docstring_line(module.strip(), attr.strip(), hops=3)


def _docstring_line(module: str, name: str, hops: int) -> str | None:
    path = _source_file(module)
    try:
        tree = ast.parse(path.read_text()) if path else None
    except (OSError, SyntaxError, ValueError):
        return None
    for node in tree.body if tree else []:
        if isinstance(node, ast.FunctionDef) and node.name == name:
            doc = (ast.get_docstring(node) or "").strip()
            return doc.splitlines()[0] if doc else None
        if isinstance(node, ast.ImportFrom) and hops and any(a.name == name and not a.asname for a in node.names):
            package = module if path.name == "__init__.py" else module.rpartition(".")[0]
            base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
            source = ".".join(filter(None, [base if node.level else "", node.module or ""]))
            return _docstring_line(source, name, hops - 1)
    return None


def _group_summary(prefix: tuple[str, ...], entries: list[EntryPoint]) -> str:
    """A group's help line (``certs``, ``evaluate``): each of its commands with the first clause of its own line."""
    words = []
    for ep in entries:
        path = tuple(ep.name.split("."))
        if path[: len(prefix)] == prefix:
            line = re.split(r"[:;(]|\.(?:\s|$)", summary(ep) or "")[0].strip().rstrip(",")
            words.append(f"{path[len(prefix)]}: {line[:1].lower()}{line[1:]}" if line else path[len(prefix)])
    return "; ".join(words)


def _unavailable(name: str, exc: Exception) -> int:
    print(f"handflow {name.replace('.', ' ')} is unavailable: {type(exc).__name__}: {exc}", file=sys.stderr)
    return 1


def _parse(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """The arguments; a command that sets ``late_positionals`` (names of optional positionals) takes them also
    after an option (``param load --restart FILE``), which argparse alone leaves unrecognised."""
    args, extra = parser.parse_known_args(argv)
    for name in getattr(args, "late_positionals", ()):
        if getattr(args, name, None) is None and extra and not extra[0].startswith("-"):
            setattr(args, name, extra.pop(0))
    if extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    return args


def _terminated(signum, frame) -> None:
    raise KeyboardInterrupt  # SIGTERM stops a command like Ctrl-C does (commands install finer handlers)


def _stdout_gone() -> bool:
    """Whether stdout is a pipe whose reader has gone (``handflow inspect F | head -1``): its write end then
    polls as an error.  Another broken pipe (a socket, a child's stdin) is not this."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll, or a stdout without a file descriptor
        return False


def main(argv: list[str] | None = None) -> int:
    """Run one command; its exit code.  A reader of stdout that goes away early ends the command quietly
    with 141 (128 + SIGPIPE, what a shell shows for ``yes | head -1``'s ``yes``), every ``finally`` of the
    command having run, and no traceback (docs/reliability.md)."""
    try:
        try:
            return _main(argv)
        finally:
            sys.stdout.flush()  # the output still buffered fails here, not in the interpreter's exit
    except BrokenPipeError:
        if not _stdout_gone():
            raise
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing left to flush at exit
        return 141


def _main(argv: list[str] | None) -> int:
    signal.signal(signal.SIGTERM, _terminated)
    try:
        parser = build_parser(argv)
        args = _parse(parser, argv)
        logging.basicConfig(
            level=args.log_level, stream=sys.stderr, format="%(asctime)s %(levelname)s [%(name)s] %(message)s"
        )
        func = getattr(args, "func", None)
        if func is None:
            parser.print_help()
            return 2
        return int(func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
