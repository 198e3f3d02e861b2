"""``handflow certs init DIR`` and ``handflow certs add-host DIR NAME`` (docs/security.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register_init(parser: argparse.ArgumentParser) -> None:
    """Create a certificate authority (ca.pem, ca.key) for the machines of a graph."""
    parser.add_argument("directory", type=Path, help="where to write ca.pem and ca.key (keep ca.key private)")
    parser.add_argument("--days", type=int, default=3650, help="validity of the CA in days (default 3650)")
    parser.set_defaults(func=_init)


def register_add_host(parser: argparse.ArgumentParser) -> None:
    """Create NAME.pem and NAME.key signed by the CA in DIR; NAME is the host name used in the graph."""
    parser.add_argument("directory", type=Path, help="directory made by `handflow certs init`")
    parser.add_argument("name", help="host name: a graph 'host:' value, or a monitoring machine named in 'readers'")
    parser.add_argument("--days", type=int, default=825, help="validity in days (default 825)")
    parser.set_defaults(func=_add_host)


def _init(args: argparse.Namespace) -> int:
    from ..security.certs import CertError, init_ca

    try:
        path = init_ca(args.directory, args.days)
    except CertError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{path}: CA created; now run `handflow certs add-host {args.directory} NAME` for every machine")
    return 0


def _add_host(args: argparse.Namespace) -> int:
    from ..security.certs import CertError, add_host

    try:
        path = add_host(args.directory, args.name, args.days)
    except CertError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{path}: certificate for '{args.name}'; copy ca.pem, {args.name}.pem and {args.name}.key to that machine")
    return 0
