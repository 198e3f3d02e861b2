"""Markdown tables from `handflow evaluate segmentation --json` results, with the manifold methods
compared against the better of the two baselines measured in the same run.

    handflow evaluate segmentation DATA.npz --json > result.json
    python benchmarks/segmentation_eval.py result.json [--json]
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

EXPERIMENTS = ("single", "concatenated", "middle_halves", "reversed_rejection", "left_out_rejection")
BASELINES = ("dtw_1nn", "hmm")


def thesis_subset(result: dict, method: str) -> dict:
    """Single letters with N^th ∈ {1, 2} — the subset of the thesis' headline figures."""
    c = np.array([x["correct"] for x in result["methods"][method]["single"]["cases"] if x["nth"] in (1, 2)])
    return {"share_ge_85": float(np.mean(c >= 0.85)), "share_perfect": float(np.mean(c >= 1.0)), "n": int(c.size)}


def table(result: dict) -> str:
    lines = ["| method | " + " | ".join(EXPERIMENTS) + " |", "|---|" + "---|" * len(EXPERIMENTS)]
    for m, exps in result["methods"].items():
        cells = []
        for e in EXPERIMENTS:
            r = exps[e]
            cell = f"{r['share_ge_85']:.2f} / {r['share_perfect']:.2f} / {r['mean_correct']:.2f}"
            if "strong_background" in r:
                s = r["strong_background"]
                cell += f" (strong: {s['share_ge_85']:.2f} / {s['share_perfect']:.2f} / {s['mean_correct']:.2f})"
            cells.append(cell)
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ratios(result: dict) -> dict:
    """mean_correct of each manifold method divided by the better baseline's, per experiment."""
    out = {}
    for m in ("ukr_only", "ukr_clm"):
        if m not in result["methods"]:
            continue
        out[m] = {}
        for e in EXPERIMENTS:
            base = max(result["methods"][b][e]["mean_correct"] for b in BASELINES if b in result["methods"])
            out[m][e] = result["methods"][m][e]["mean_correct"] / base if base else None
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("result", help="JSON written by `handflow evaluate segmentation --json`")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    with open(args.result) as f:
        result = json.load(f)
    summary = {
        "ratios_vs_best_baseline": ratios(result),
        "single_nth_1_2": {m: thesis_subset(result, m) for m in result["methods"]},
        "selected": result["parameters"]["selected"],
        "runtime_s": result.get("runtime_s"),
    }
    if args.json:
        print(json.dumps(summary, indent=1))
        return 0
    print("cells: share ≥ 85 % / share 100 % / mean correct\n")
    print(table(result))
    print("\nmean correct vs the better baseline (ratio):")
    for m, r in summary["ratios_vs_best_baseline"].items():
        print(f"- {m}: " + ", ".join(f"{e} {v:.2f}" for e, v in r.items() if v is not None))
    print(
        "\nsingle, N^th ∈ {1,2}: "
        + "; ".join(
            f"{m} {v['share_ge_85']:.3f} ≥85 %, {v['share_perfect']:.3f} perfect (n={v['n']})"
            for m, v in summary["single_nth_1_2"].items()
        )
    )
    print(f"\nselected parameters: {summary['selected']}; runtime {summary['runtime_s']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
