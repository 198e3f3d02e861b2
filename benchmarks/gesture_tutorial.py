"""docs/tutorial_gestures.md from an empty directory: wall and CPU time per command and the recognition figures
(docs/benchmarks.md, "Teach your own gestures").

Runs the page's ```bash commands as written, in order, in a fresh temporary directory, and times each
one (wall, and the CPU time of its processes: on a shared machine the wall time depends on the load);
then reads the figures the page names: the dataset's repetitions, the leave-one-recording-out
estimate (``out/check.json``), and on the live run the share of frames of each performed gesture
labelled right — live (labels on arrival) and in the lock-step replay (final labels) — and the share
of the untaught ``turn`` labelled unknown.  Baseline, measured in the same run on the same live
recording: models trained by ``train-classes`` with its own defaults (no ``--params``), replayed in
lock-step the same way.  The machine's load average is printed with the figures.

    python benchmarks/gesture_tutorial.py --json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import tempfile
import time
from pathlib import Path

from handflow.framework.files.labels import recognition_shares

PAGE = Path(__file__).resolve().parents[1] / "docs" / "tutorial_gestures.md"
TAUGHT = ("grasp", "pinch", "wave")


def page_commands(page: Path = PAGE) -> list[str]:
    """The commands of the page's ```bash blocks, as written."""
    blocks = re.findall(r"^```bash\n(.*?)^```", page.read_text(), re.S | re.M)
    return [line.strip() for b in blocks for line in b.splitlines() if line.strip() and not line.startswith("#")]


def timed(cmd: str, cwd: Path) -> tuple[float, float]:
    """Wall and CPU seconds (user + system of the command and every process it waited for) of ``cmd``."""
    t0, c0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(["bash", "-c", cmd], cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{cmd} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = c1.ru_utime - c0.ru_utime + c1.ru_stime - c0.ru_stime
    return round(time.perf_counter() - t0, 1), round(cpu, 1)


def shares(ws: Path, replayed: str) -> dict:
    live = recognition_shares(ws / "out/live.mcap", "glove/performed", "segmenter/labels", revisions=False)
    again = recognition_shares(ws / replayed, "glove/performed", "segmenter/labels", ws / "out/live.mcap")
    return {
        "live_right": {g: live[g]["right"] for g in TAUGHT},
        "lockstep_right": {g: again[g]["right"] for g in TAUGHT},
        "turn_unknown_live": live["turn"]["unknown"],
        "turn_unknown_lockstep": again["turn"]["unknown"],
        "rest_unknown_lockstep": again.get("rest", {}).get("unknown"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        ws = Path(tmp)
        commands = page_commands()
        steps = []
        for cmd in commands:
            wall, cpu = timed(cmd, ws)
            steps.append({"command": cmd.split(" --")[0], "seconds": wall, "cpu_s": cpu})
        total = round(sum(s["seconds"] for s in steps), 1)
        cpu_total = round(sum(s["cpu_s"] for s in steps), 1)
        check = json.loads((ws / "out/check.json").read_text())["methods"]["ukr_clm"]
        ours = shares(ws, "out/replayed.mcap")
        timed("handflow train-classes out/gestures.npz --out models_default", ws)
        timed(
            "handflow replay out/live.mcap --into segment_gestures --set segmenter.models=models_default "
            "--lockstep --record out/replayed_default.mcap",
            ws,
        )
        baseline = shares(ws, "out/replayed_default.mcap")
    result = {
        "wall_s": total,
        "cpu_s": cpu_total,
        "handflow_commands": sum(c.startswith("handflow ") for c in commands),
        "steps": steps,
        "estimate": {k: round(check[k], 4) for k in ("open_set_accuracy", "known_accuracy", "unknown_rejection")},
        "tutorial": ours,
        "baseline_train_classes_defaults": baseline,
        "load_average": {"before": [round(x, 2) for x in load_before], "after": [round(x, 2) for x in os.getloadavg()]},
    }
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(
        f"tutorial from an empty directory: {total:.0f} s wall, {cpu_total:.0f} s CPU, "
        f"{result['handflow_commands']} handflow commands"
    )
    for s in steps:
        print(f"  {s['seconds']:7.1f} s wall {s['cpu_s']:7.1f} s CPU  {s['command']}")
    print(f"estimate (leave one recording out): {result['estimate']}")
    print(f"tutorial models: {ours}")
    print(f"baseline (train-classes defaults): {baseline}")
    print(f"load average before {load_before}, after {os.getloadavg()}")


if __name__ == "__main__":
    main()
