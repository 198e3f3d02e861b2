"""Model files: one ``.npz`` of plain arrays + a JSON metadata string (docs/training.md).

Never pickled: files are read with ``np.load(..., allow_pickle=False)``, so loading a model
cannot execute code.  Metadata: ``format``, ``format_version``, all hyper-parameters, the time
dimension, the final objective, provenance (software version, time of creation, plus whatever
the caller passes: source recording, topic, time ranges …).
"""

from __future__ import annotations

import datetime as _dt
import json

import numpy as np

from handflow.framework.files.npz import NpzFileError, building, npz_metadata, read_npz
from handflow.framework.files.provenance import installed_version

FORMAT = "handflow.structured_ukr"
FORMAT_VERSION = 1
_ARRAYS = ("Y", "latents", "sequence_ids", "train_variance", "history")
RETRAIN = "train it again with `handflow train` (docs/training.md)"


def _json_params(model):
    params = model.get_params()
    params["latent"] = [dict(getattr(d, "__dict__", d)) for d in (params["latent"] or [])] or None
    params["isomap_neighbors"] = [int(k) for k in params["isomap_neighbors"]]
    if not isinstance(params["init"], str):
        params["init"] = "given"
    if not isinstance(params["random_state"], (int, type(None))):
        params["random_state"] = None
    return params


def save_model(model, path, provenance=None):
    """Write ``model`` (fitted) to ``path`` (.npz)."""
    prov = {
        "software": "handflow",
        "software_version": installed_version(),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    prov.update(getattr(model, "provenance_", {}) or {})
    prov.update(provenance or {})
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "params": _json_params(model),
        "time_dim": model.time_dim_,
        "objective": float(model.objective_),
        "interrupted": bool(model.interrupted_),
        "n_evaluations": int(model.n_evaluations_),
        "init_info": _jsonable(model.init_info_),
        "provenance": _jsonable(prov),
    }
    ids = model.sequence_ids_
    if ids.dtype == object:
        ids = ids.astype(str)
    with open(path, "wb") as fh:
        np.savez(
            fh,
            Y=model.Y_,
            latents=model.latents_,
            sequence_ids=ids,
            train_variance=model.train_variance_,
            history=model.history_,
            metadata=np.array(json.dumps(meta)),
        )


def _jsonable(obj):
    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


def load_model(cls, path):
    """Read a model file; refuses other formats and unknown format versions.

    The loaded estimator's ``init`` is its stored latents (refitting continues from them).  Any
    bad file — missing, unreadable, foreign, another version, garbled — raises
    :class:`~handflow.framework.files.npz.NpzFileError` (a ``ValueError``) naming it.
    """
    what, hint = "Structured UKR model", RETRAIN
    arrays = read_npz(path, what, hint)
    meta = npz_metadata(arrays, path, what, hint, fmt=(FORMAT, FORMAT_VERSION, "format_version"))
    missing = [k for k in _ARRAYS if k not in arrays]
    if missing:
        raise NpzFileError(f"{path}: model file is missing arrays {missing}; {hint}")
    with building(path, what, hint):
        params = dict(meta["params"])
        params["isomap_neighbors"] = tuple(params["isomap_neighbors"])
        params["init"] = arrays["latents"]
        model = cls(**params)
        kernel, time_dim = model._layout()
        _check_arrays(arrays, len(kernel.periodic))
        model._set_state(
            arrays["Y"], arrays["latents"], arrays["sequence_ids"], time_dim, kernel, arrays["train_variance"]
        )
        model.history_ = arrays["history"]
        model.objective_ = meta["objective"]
        model.interrupted_ = meta["interrupted"]
        model.init_info_ = meta.get("init_info", {})
        model.n_evaluations_ = meta["n_evaluations"]
        model.provenance_ = meta["provenance"]
        if not isinstance(model.provenance_, dict) or not isinstance(model.init_info_, dict):
            raise ValueError("provenance and init_info must be JSON objects")
    return model


def _check_arrays(arrays: dict, q: int) -> None:
    """The stored arrays agree with each other and with the ``q`` latent dimensions of the params."""
    Y, X = arrays["Y"], arrays["latents"]
    n = len(Y)
    if (
        Y.ndim != 2
        or X.shape != (n, q)
        or arrays["sequence_ids"].shape != (n,)
        or arrays["train_variance"].shape != (Y.shape[1],)
        or Y.dtype.kind != "f"
        or X.dtype.kind != "f"
        or not (np.isfinite(Y).all() and np.isfinite(X).all() and (arrays["train_variance"] > 0).all())
    ):
        raise ValueError("arrays Y, latents, sequence_ids and train_variance disagree with each other or the params")
