"""``handflow plugins``."""

from __future__ import annotations

import argparse
import json
import sys

from ..files.params import live_keys
from ..registry import PluginError, plugin_entries, unknown_plugin


def register(parser: argparse.ArgumentParser) -> None:
    """List installed plugins with their ports and parameters."""
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument("name", nargs="?", help="show only this plugin")
    parser.set_defaults(func=run)


def _describe(name: str) -> dict:
    entry = plugin_entries()[name]
    try:
        cls = entry.load()
    except PluginError as exc:
        return {"name": name, "target": entry.target, "error": str(exc)}
    params = {}
    live = live_keys(cls.Params)
    for fname, f in cls.Params.model_fields.items():
        ann = getattr(f.annotation, "__name__", None) or str(f.annotation).replace("typing.", "")
        default = None if f.is_required() else f.get_default(call_default_factory=True)
        params[fname] = {
            "type": ann,
            "default": default,
            "required": f.is_required(),
            "live": fname in live,  # takes a new value while running (docs/tuning.md)
            "help": f.description or "",
        }
    return {
        "name": name,
        "target": entry.target,
        "summary": cls.summary(),
        "inputs": {p: t.TYPE or "any" for p, t in cls.inputs.items()},
        "outputs": {p: t.TYPE or "any" for p, t in cls.outputs.items()},
        "params": params,
    }


def run(args: argparse.Namespace) -> int:
    names = sorted(plugin_entries())
    if args.name:
        if args.name not in names:
            print(unknown_plugin(args.name), file=sys.stderr)
            return 2
        names = [args.name]
    infos = [_describe(n) for n in names]
    if args.json:
        print(json.dumps(infos, indent=2, default=str))
        return 0
    for info in infos:
        print(f"{info['name']}  ({info['target']})")
        if "error" in info:
            print(f"    UNAVAILABLE: {info['error']}")
            continue
        if info["summary"]:
            print(f"    {info['summary']}")
        for kind in ("inputs", "outputs"):
            if info[kind]:
                print(f"    {kind}: " + ", ".join(f"{p} [{t}]" for p, t in info[kind].items()))
        for pname, p in info["params"].items():
            default = ("required" if p["required"] else f"default {p['default']!r}") + (", live" if p["live"] else "")
            print(f"    param {pname}: {p['type']} ({default}){'  ' + p['help'] if p['help'] else ''}")
    return 0
