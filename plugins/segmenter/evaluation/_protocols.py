"""What an evaluation's figures are (docs/segmentation.md, "Which protocol when"): the JSON's
top-level ``protocol`` — ``"nested"``, the figure to publish, or ``"preview"``, cross-validated
grid search for exploring — with the reason the figure can or cannot be optimistic."""

from __future__ import annotations

_REASONS = {
    ("nested", "recordings"): "every fold's view, grid point and rejection value are chosen on inner folds of its "
    "training recordings: the held-out recording takes no part in any choice (the figure to publish)",
    ("nested", "trajectories"): "every method's grid point and heading channels are chosen on the validation split "
    "and on cross-fitted splits of the training and validation trajectories: the test cases take no part in any "
    "choice (the figure to publish)",
    ("preview", "recordings"): "cross-validated grid search, like scikit-learn's best_score_: every candidate is "
    "scored on the held-out recordings themselves and the one with the best pooled objective is reported on those "
    "same recordings, so the figure includes the luck of that choice; one choice for all folds, no refit (for "
    "exploring; publish the nested protocol's figure)",
    ("preview", "trajectories"): "grid search on the test cases, like scikit-learn's best_score_: every candidate "
    "(heading channels × grid point) is scored on the test cases that are reported and the best is reported on "
    "them, so the figure includes the luck of that choice; no validation round, no cross-fitted heading splits "
    "(for exploring; publish the nested protocol's figure)",
}


def protocol(preview: bool, data: str) -> dict:
    """The JSON's ``protocol`` of an evaluation of ``data`` (``"recordings"``, ``"trajectories"``)."""
    name = "preview" if preview else "nested"
    return {"name": name, "optimistic": preview, "reason": _REASONS[name, data]}
