"""Input checks with messages that say what to change (docs/training.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels import KERNEL_NAMES, Kernel, ProductKernel


class InvalidInputError(ValueError):
    """Bad data or configuration (the ``train`` command exits with status 2)."""


@dataclass(frozen=True)
class LatentDim:
    """One latent dimension: kernel name, inverse bandwidth β, whether it is the time dim."""

    kernel: str
    beta: float
    time: bool = False


DEFAULT_LATENT = ({"kernel": "periodic", "beta": 12.0, "time": True},)


def parse_latent(latent):
    """Latent layout (list of dicts / :class:`LatentDim`) → ``(ProductKernel, time_dim)``."""
    dims = DEFAULT_LATENT if latent is None else latent
    if isinstance(dims, (dict, LatentDim)) or not len(dims):
        raise InvalidInputError(
            "latent must be a non-empty list with one entry per latent "
            "dimension, e.g. [{'kernel': 'periodic', 'beta': 12, 'time': True}]"
        )
    kernels, times = [], []
    for l, dim in enumerate(dims):
        d = dim.__dict__ if isinstance(dim, LatentDim) else dict(dim)
        unknown = set(d) - {"kernel", "beta", "time"}
        if unknown or "kernel" not in d or "beta" not in d:
            raise InvalidInputError(f"latent[{l}] must have keys kernel, beta and optional time; got {sorted(d)}")
        if d["kernel"] not in KERNEL_NAMES:
            raise InvalidInputError(
                f"latent[{l}]: unknown kernel {d['kernel']!r}; choose one of {', '.join(KERNEL_NAMES)}"
            )
        try:
            kernels.append(Kernel(d["kernel"], float(d["beta"])))
        except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: float() of a huge integer
            raise InvalidInputError(f"latent[{l}]: {exc}") from None
        if d.get("time", False):
            times.append(l)
    if len(times) > 1:
        raise InvalidInputError(
            f"only one latent dimension can be the time dimension; got time: true on dimensions {times}"
        )
    return ProductKernel(kernels), (times[0] if times else None)


def check_time_dim(time_dim, q):
    """A time dimension given as an index must exist in the latent layout."""
    if time_dim is not None and not 0 <= time_dim < q:
        raise InvalidInputError(
            f"time dimension index {time_dim} is out of range for a {q}-dimensional latent space (valid: 0…{q - 1})"
        )


def as_sequences(sequences, sequence_ids=None):
    """Normalise the fit input to ``(Y (N×d) float array, sequence ids (N,))``.

    Accepts a list of ``(n_i, d)`` arrays (one ordered sequence each) or one ``(N, d)`` array
    with optional ``sequence_ids`` (default: a single sequence).
    """
    if isinstance(sequences, (list, tuple)):
        if sequence_ids is not None:
            raise InvalidInputError("give sequence_ids only with a single (N, d) array")
        if not sequences:
            raise InvalidInputError("no sequences given")
        arrays = [check_array(s, f"sequence {i}") for i, s in enumerate(sequences)]
        dims = {a.shape[1] for a in arrays}
        if len(dims) > 1:
            shapes = ", ".join(f"{i}: {a.shape[1]}" for i, a in enumerate(arrays))
            raise InvalidInputError(
                f"inconsistent dimensions: all sequences need the same number of columns (got {shapes})"
            )
        ids = np.repeat(np.arange(len(arrays)), [len(a) for a in arrays])
        return np.vstack(arrays), ids
    Y = check_array(sequences, "Y")
    ids = np.zeros(len(Y), dtype=int) if sequence_ids is None else np.asarray(sequence_ids)
    if ids.shape != (len(Y),):
        raise InvalidInputError(f"sequence_ids must have one entry per row of Y ({len(Y)}), got shape {ids.shape}")
    return Y, ids


def check_array(a, name="Y", ndim=2, columns=None):
    """Float array of the given ndim, all finite, with ``columns`` columns if given."""
    try:
        a = np.asarray(a, dtype=float)
    except (TypeError, ValueError, OverflowError):  # OverflowError: a huge integer
        raise InvalidInputError(f"{name} must be numeric") from None
    if a.ndim != ndim:
        raise InvalidInputError(f"{name} must be {ndim}-dimensional, got shape {a.shape}")
    if ndim == 2 and a.shape[0] == 0:
        raise InvalidInputError(f"{name} is empty")
    if columns is not None and a.shape[-1] != columns:
        raise InvalidInputError(
            f"inconsistent dimensions: {name} has {a.shape[-1]} columns, the model expects {columns}"
        )
    bad = ~np.isfinite(a)
    if bad.any():
        where = np.argwhere(bad)[0]
        raise InvalidInputError(
            f"{name} contains NaN or inf ({int(bad.sum())} values, first "
            f"at index {tuple(int(i) for i in where)}); clean or drop those "
            f"rows"
        )
    return a
