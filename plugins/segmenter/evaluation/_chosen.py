"""Parameters chosen by an earlier evaluation (``--params RESULT.json``, docs/segmentation.md,
"Continuous recordings"): per method and held-out recording, the view, grid point and
rejection value that run's selection chose, so a rerun skips the selection.  A recording that run
did not hold out gets the method's *most frequent* choice (documented choice: the set chosen in
most folds, ties to the earliest fold) — the set ``train-classes --params`` trains too."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from ._calibration import Choice

REPORTED = ("reject", "validation_objective", "rejection", "strict", "enrol_adaptation", "enrol_validation")


class ChosenParameters:
    """The choices of a result of ``evaluate segmentation --json`` on continuous recordings.

    ``result``: the parsed JSON; a ValueError names what is missing when it is not one."""

    def __init__(self, result: dict, source: str = "the result") -> None:
        methods = result.get("methods") if isinstance(result, dict) else None
        if not isinstance(methods, dict) or not all(isinstance(r, dict) and "folds" in r for r in methods.values()):
            raise ValueError(
                f"{source} is not the --json output of 'handflow evaluate segmentation' on continuous recordings "
                "(it needs methods → folds → selected)"
            )
        self.source = source
        self.by_method = {
            name: [(str(f["recording"]), f["selected"]) for f in res["folds"]] for name, res in methods.items()
        }

    @classmethod
    def load(cls, path: str | Path) -> ChosenParameters:
        """The choices in the JSON file ``path``."""
        try:
            result = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"--params {path}: cannot read it as JSON ({exc})") from exc
        return cls(result, f"--params {path}")

    def check(self, methods: tuple[str, ...], normalise: tuple[str, ...], derived: tuple[str, ...]) -> None:
        """A ValueError that says what to change when a method has no choice in the result or a
        choice needs a view the evaluation does not build."""
        missing = [m for m in methods if m not in self.by_method]
        if missing:
            raise ValueError(
                f"{self.source} has no parameters for {missing} (it has {sorted(self.by_method)}): leave them out "
                "of --methods or evaluate them without --params"
            )
        for name in methods:
            for _, sel in self.by_method[name]:
                if sel["normalise"] not in normalise or sel["derived"] not in derived:
                    raise ValueError(
                        f"{self.source} chose normalisation {sel['normalise']!r} and derived features "
                        f"{sel['derived']!r} for {name}: keep them in --normalise and --derived"
                    )

    def selected(self, name: str, recording: str) -> dict:
        """The entry ``selected`` of method ``name`` for held-out ``recording``, or its most frequent one."""
        chosen = dict(self.by_method[name])
        return chosen[recording] if recording in chosen else self.most_frequent(name)

    def most_frequent(self, name: str) -> dict:
        """The set of parameters chosen in most folds (rejection included), ties to the earliest fold."""
        sets = [sel for _, sel in self.by_method[name]]
        keys = [json.dumps(_without_scores(sel), sort_keys=True) for sel in sets]
        counts = Counter(keys)
        return sets[max(range(len(sets)), key=lambda i: (counts[keys[i]], -i))]

    def choice(self, name: str, recording: str) -> Choice:
        """:class:`Choice` of method ``name`` for held-out ``recording``."""
        sel = self.selected(name, recording)
        strict = sel.get("strict")
        return Choice(
            params=parameters(sel),
            reject=float(sel["reject"]),
            objective=float(sel["validation_objective"]),
            fallback=sel["rejection"] == "off",
            strict=None if strict is None else Choice(parameters(strict), float(strict["reject"]), float("nan")),
        )


def parameters(selected: dict) -> dict:
    """The parameters of a ``selected`` entry: its view and grid point, without what was reported."""
    return {k: v for k, v in selected.items() if k not in REPORTED}


def _without_scores(selected: dict) -> dict:
    """What identifies a choice: all but the validation figures, which differ between folds."""
    return {k: v for k, v in selected.items() if k not in ("validation_objective", "enrol_validation")}
