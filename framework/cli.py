"""The ``handflow`` command: sub-commands are entry points of group ``handflow.commands``.

Each entry point names ``register(parser)``, which adds its arguments to its sub-parser and sets
``func=run`` where ``run(args) -> int`` is the exit code.  Dotted names nest (``evaluate.grasping``
→ ``handflow evaluate grasping``), so families add commands without touching the framework.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys

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
    for ep in command_entries():
        path = tuple(ep.name.split("."))
        for depth in range(1, len(path)):
            prefix = path[:depth]
            if prefix not in subparsers:
                grp = subparsers[prefix[:-1]].add_parser(
                    prefix[-1], help=f"{prefix[-1]} … (see `handflow {prefix[-1]} -h`)"
                )
                subparsers[prefix] = grp.add_subparsers(dest=f"command_{depth}", metavar="WHAT")
        parent = subparsers[path[:-1]]
        if requested[: len(path)] != path:
            parent.add_parser(path[-1], help=f"see `handflow {' '.join(path)} -h`")
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


def _unavailable(name: str, exc: Exception) -> int:
    print(f"handflow {name.replace('.', ' ')} is unavailable: {type(exc).__name__}: {exc}", file=sys.stderr)
    return 1


def _terminated(signum, frame) -> None:
    raise KeyboardInterrupt  # SIGTERM stops a command like Ctrl-C does (commands install finer handlers)


def main(argv: list[str] | None = None) -> int:
    signal.signal(signal.SIGTERM, _terminated)
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
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
