"""``handflow plugins``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..files.params import live_keys
from ..registry import PluginError, is_path_plugin, load_file_plugin, plugin_entries, unknown_plugin


def register(parser: argparse.ArgumentParser) -> None:
    """List installed plugins with their ports and parameters."""
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument(
        "name", nargs="?", help="show only this plugin (or a plugin file, ./my_plugin.py:MyNode, relative to here)"
    )
    parser.set_defaults(func=run)


def _describe(name: str) -> dict:
    if is_path_plugin(name):  # as a graph in the current folder would name it (docs/pipelines.md)
        target, load = str(Path(name.rpartition(":")[0]).resolve()), lambda: load_file_plugin(name, Path.cwd())
    else:
        entry = plugin_entries()[name]
        target, load = entry.target, entry.load
    try:
        cls = load()
    except PluginError as exc:
        return {"name": name, "target": target, "error": str(exc)}
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
        "target": target,
        "summary": cls.summary(),
        "inputs": {p: t.TYPE or "any" for p, t in cls.inputs.items()},
        "outputs": {p: t.TYPE or "any" for p, t in cls.outputs.items()},
        "params": params,
    }


def run(args: argparse.Namespace) -> int:
    names = sorted(plugin_entries())
    if args.name:
        if args.name not in names and not is_path_plugin(args.name):
            print(unknown_plugin(args.name), file=sys.stderr)
            return 2
        names = [args.name]
    infos = [_describe(n) for n in names]
    code = 2 if args.name and is_path_plugin(args.name) and "error" in infos[0] else 0  # a file that does not load
    if args.json:
        print(json.dumps(infos, indent=2, default=str))
        return code
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
    return code
