"""``handflow ros2-topics``: the ROS 2 topics visible over Zenoh, as ``ros2 topic list -v`` shows them (docs/ros2.md)."""

from __future__ import annotations

import argparse
import collections
import json

import zenoh

from ..messages import MessageError
from ..ros2.rmw_zenoh import ADMIN_SPACE, parse_token


def register(parser: argparse.ArgumentParser) -> None:
    """List ROS 2 topics, their types and publisher/subscription counts from rmw_zenoh liveliness tokens."""
    parser.add_argument(
        "--connect", action="append", help="Zenoh endpoint of the ROS 2 system (repeatable; default tcp/localhost:7447)"
    )
    parser.add_argument("--domain-id", type=int, default=0, help="ROS_DOMAIN_ID (default 0)")
    parser.add_argument("--timeout", type=float, default=2.0, help="seconds to wait for answers (default 2)")
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(func=run)


def topics(session: zenoh.Session, domain_id: int, timeout_s: float) -> dict[str, dict[str, object]]:
    """``/topic`` → type, hash, publisher and subscription counts, as announced by liveliness tokens."""
    table: dict[str, dict[str, object]] = {}
    counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for reply in session.liveliness().get(f"{ADMIN_SPACE}/{domain_id}/**", timeout=timeout_s):
        if reply.ok is None:
            continue
        try:
            entity = parse_token(str(reply.ok.key_expr))
        except MessageError:
            continue
        if entity.kind in ("MP", "MS"):
            table.setdefault(entity.topic, {"type": entity.ros_type, "type_hash": entity.type_hash})
            counts[entity.topic][entity.kind] += 1
    for topic, row in table.items():
        row.update(publishers=counts[topic]["MP"], subscriptions=counts[topic]["MS"])
    return dict(sorted(table.items()))


def run(args: argparse.Namespace) -> int:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps(args.connect or ["tcp/localhost:7447"]))
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as exc:
        where = ", ".join(args.connect or ["tcp/localhost:7447"])
        print(
            f"cannot reach the ROS 2 system at {where} ({str(exc).split('!')[0]}); start its router "
            "(ros2 run rmw_zenoh_cpp rmw_zenohd) or give --connect ENDPOINT"
        )
        return 2
    try:
        table = topics(session, args.domain_id, args.timeout)
    finally:
        session.close()
    if args.json:
        print(json.dumps(table, indent=2))
    elif not table:
        print(f"no ROS 2 topics in domain {args.domain_id}")
    for topic, row in ({} if args.json else table).items():
        print(f"{topic} [{row['type']}] {row['publishers']} publisher(s), {row['subscriptions']} subscription(s)")
    return 0
