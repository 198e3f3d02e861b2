"""`handflow evaluate segmentation --cache DIR` run twice on continuous recordings
(docs/benchmarks.md, "Evaluation speed"): the first run computes and keeps every method's part of
every fold, the second takes them from DIR. Prints both runs' ``runtime_s``, the second's share of
the first and whether the two JSONs are identical but for ``runtime_s`` and ``timing`` (exit code 1
otherwise).

    python benchmarks/evaluation_cache.py bm.npz [--methods ...] [--json] [-- extra evaluate options]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile


def evaluation(recordings: str, cache: str, extra: list[str]) -> dict:
    cmd = ["handflow", "evaluate", "segmentation", recordings, "--quick", "--json", "--cache", cache, *extra]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings")
    parser.add_argument("--methods")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("extra", nargs="*", help="more options of 'evaluate segmentation' (after --)")
    args = parser.parse_args()
    extra = [*(["--methods", args.methods] if args.methods else []), *args.extra]
    with tempfile.TemporaryDirectory() as cache:
        first, second = (evaluation(args.recordings, cache, extra) for _ in range(2))
    seconds = [r.pop("runtime_s") for r in (first, second)]
    for r in (first, second):
        r.pop("timing")
    figure = {
        "first_s": seconds[0],
        "second_s": seconds[1],
        "second_share": round(seconds[1] / seconds[0], 4),
        "identical": first == second,
    }
    print(json.dumps(figure) if args.json else "\n".join(f"{k}: {v}" for k, v in figure.items()))
    return 0 if figure["identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
