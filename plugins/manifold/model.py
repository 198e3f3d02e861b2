"""The Structured UKR estimator (docs/training.md; thesis 2.1 and 5.3), scikit-learn conventions."""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from .init import equidistant_init, isomap_init
from .io import load_model, save_model
from .objective import Objective, SequenceLayout
from .optimize import OPTIMIZERS
from .projection import Manifold
from .sparse import SparseManifold, SparseObjective, use_sparse
from .validation import InvalidInputError, as_sequences, check_array, check_time_dim, parse_latent

INIT_NAMES = ("isomap", "equidistant")


class StructuredUKR(BaseEstimator):
    """Structured Unsupervised Kernel Regression.

    Parameters
    ----------
    latent : list of dict or LatentDim, default one periodic time dimension with β = 12
        One entry per latent dimension: ``kernel`` (gaussian | periodic | quartic | periodic_quartic |
        epanechnikov), inverse bandwidth ``beta`` and ``time`` (at most one), docs/training.md
    time_dim : int, optional
        Index of the time dimension — alternative to ``time: true`` in ``latent``.
    lambda_cseq, lambda_pvar : float
        Weights of the sequence-order and parameter-variance penalties (§4); they need a time
        dimension.
    loo_cv : bool
        Leave-one-out cross-validated reconstruction error (§4).
    optimizer : 'rprop' | 'lbfgs'
        iRprop− (the thesis) or scipy's L-BFGS-B (§5).
    n_steps : int
        Optimisation steps (iterations for L-BFGS); 0 builds the model from the init latents.
    init : 'isomap' | 'equidistant' | array (N, q) | list of (n_i, q) arrays
        §6.  Given latents are used as they are (periodic coordinates taken modulo π).
    isomap_neighbors : sequence of int
        Candidate K for the Isomap init; the best by R_cv after the scale search is kept.
    projection_steps : int
        Levenberg–Marquardt refinement steps of ``transform`` (§7).
    random_state : int, Generator or None
        Seeds the symmetry-breaking jitter of the equidistant init (the rest is deterministic).
    sparse : 'auto' | True | False | 'float32'
        Neighbour-list objective and mapping, linear in N (compact kernels only; 'float32'
        evaluates it in single precision); 'auto' takes it for compact kernels from
        ``SPARSE_MIN_N`` points on (docs/training.md, "Training at scale").

    Attributes (after ``fit``)
    --------------------------
    latents_ (N, q), Y_ (N, d), sequence_ids_ (N,), history_ (objective per step, index 0 =
    initial), objective_ (best value), train_variance_ (d,), time_dim_ (int or None),
    periodic_ (q,) bool, sparse_ (bool), init_info_, interrupted_, n_evaluations_, n_features_in_,
    provenance_ (dict saved with the model).

    Examples
    --------
    >>> import numpy as np
    >>> from handflow.plugins.manifold import StructuredUKR
    >>> phase = 2 * np.pi * np.arange(40) / 40
    >>> circles = [np.c_[np.cos(phase), np.sin(phase), 0.1 * k + 0 * phase] for k in range(2)]
    >>> latent = [{"kernel": "periodic", "beta": 12, "time": True}]
    >>> ukr = StructuredUKR(latent=latent, n_steps=5, init="equidistant", random_state=0).fit(circles)
    >>> ukr.latents_.shape, ukr.transform(circles[0]).shape
    ((80, 1), (40, 1))
    """

    def __init__(
        self,
        *,
        latent=None,
        time_dim=None,
        lambda_cseq=1.0,
        lambda_pvar=1.0,
        loo_cv=True,
        optimizer="rprop",
        n_steps=500,
        init="isomap",
        isomap_neighbors=(5, 10, 15),
        projection_steps=10,
        random_state=None,
        sparse="auto",
    ):
        self.latent = latent
        self.time_dim = time_dim
        self.lambda_cseq = lambda_cseq
        self.lambda_pvar = lambda_pvar
        self.loo_cv = loo_cv
        self.optimizer = optimizer
        self.n_steps = n_steps
        self.init = init
        self.isomap_neighbors = isomap_neighbors
        self.projection_steps = projection_steps
        self.random_state = random_state
        self.sparse = sparse

    # -- configuration ------------------------------------------------------------------------
    def _layout(self):
        """Validated ``(ProductKernel, time_dim)`` from the hyper-parameters."""
        kernel, time_dim = parse_latent(self.latent)
        if self.time_dim is not None:
            check_time_dim(int(self.time_dim), kernel.q)
            if time_dim is not None and time_dim != int(self.time_dim):
                raise InvalidInputError(
                    f"time_dim={self.time_dim} conflicts with time: true on latent dimension {time_dim}"
                )
            time_dim = int(self.time_dim)
        if time_dim is None and (self.lambda_cseq or self.lambda_pvar):
            raise InvalidInputError(
                "lambda_cseq/lambda_pvar need a time dimension: set "
                "time: true on one latent dimension or set both lambdas "
                "to 0"
            )
        if self.optimizer not in OPTIMIZERS:
            raise InvalidInputError(f"unknown optimizer {self.optimizer!r}; choose one of {', '.join(OPTIMIZERS)}")
        for name in ("n_steps", "projection_steps"):
            if int(getattr(self, name)) < 0:
                raise InvalidInputError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("lambda_cseq", "lambda_pvar"):
            if not float(getattr(self, name)) >= 0:
                raise InvalidInputError(f"{name} must be >= 0, got {getattr(self, name)}")
        return kernel, time_dim

    def _initial_latents(self, Y, objective, layout, kernel, time_dim):
        init = self.init
        if isinstance(init, str):
            if init == "isomap":
                return isomap_init(Y, objective, self.isomap_neighbors)
            if init == "equidistant":
                return equidistant_init(layout, kernel, time_dim, self.random_state), {}
            raise InvalidInputError(
                f"unknown init {init!r}; use one of {', '.join(INIT_NAMES)} or an (N, q) array of latents"
            )
        X = np.vstack(init) if isinstance(init, (list, tuple)) else init
        X = check_array(X, "init latents")
        if X.shape != (len(Y), kernel.q):
            raise InvalidInputError(
                f"init latents must have shape ({len(Y)}, {kernel.q}) "
                f"(one row per point, one column per latent dimension); "
                f"got {X.shape}"
            )
        return kernel.wrap(X), {}

    # -- training ------------------------------------------------------------------------------
    def fit(self, sequences, sequence_ids=None, callback=None):
        """Train on ordered sequences (list of (n_i, d) arrays, or (N, d) + sequence_ids).

        ``callback(step, objective)`` is called once per optimisation step.  A
        ``KeyboardInterrupt`` during optimisation stops it; the best latents so far are kept
        and ``interrupted_`` is set.
        """
        kernel, time_dim = self._layout()
        Y, ids = as_sequences(sequences, sequence_ids)
        N, d = Y.shape
        if kernel.q >= d:
            raise InvalidInputError(
                f"the latent space ({kernel.q}-D) must have fewer dimensions than the data ({d} columns)"
            )
        need = max(3, kernel.q + 2)
        if N < need:
            raise InvalidInputError(f"fewer points than needed: got {N}, a {kernel.q}-D model needs at least {need}")
        layout = SequenceLayout(ids)
        sparse = use_sparse(self.sparse, kernel, N)
        options = {"dtype": np.float32 if self.sparse == "float32" else np.float64} if sparse else {}
        objective = (SparseObjective if sparse else Objective)(
            Y,
            kernel,
            layout,
            time_dim=time_dim,
            lambda_cseq=self.lambda_cseq,
            lambda_pvar=self.lambda_pvar,
            loo_cv=self.loo_cv,
            **options,
        )
        X0, self.init_info_ = self._initial_latents(Y, objective, layout, kernel, time_dim)
        result = OPTIMIZERS[self.optimizer](objective, X0, int(self.n_steps), wrap=kernel.wrap, callback=callback)
        self._set_state(Y, kernel.wrap(result.X), ids, time_dim, kernel)
        self.history_ = np.asarray(result.history, dtype=float)
        self.objective_ = result.value
        self.n_evaluations_ = result.n_evaluations
        self.interrupted_ = result.interrupted
        self.provenance_ = {}
        return self

    def _set_state(self, Y, X, ids, time_dim, kernel, train_variance=None):
        """Set the learned attributes and the cached manifold (used by fit and load)."""
        self.Y_, self.latents_, self.sequence_ids_ = Y, X, np.asarray(ids)
        self.time_dim_ = time_dim
        self.periodic_ = kernel.periodic.copy()
        self.n_features_in_ = Y.shape[1]
        if train_variance is None:
            # Documented choice: zero-variance dimensions get variance 1 (no division by 0).
            train_variance = Y.var(axis=0)
            train_variance = np.where(train_variance > 0, train_variance, 1.0)
        self.train_variance_ = np.asarray(train_variance, dtype=float)
        self.sparse_ = use_sparse(self.sparse, kernel, len(Y))
        self._manifold = (SparseManifold if self.sparse_ else Manifold)(kernel, X, Y)

    @classmethod
    def from_latents(cls, sequences, latents, sequence_ids=None, **params):
        """Model built directly from given latents, without training (``n_steps=0``)."""
        return cls(init=latents, n_steps=0, **params).fit(sequences, sequence_ids)

    def extend(self, sequences, n_steps=None, callback=None):
        """Construction scheme step (production §2): project the new sequences onto the
        current model, merge them with the training data and retrain from the merged latents
        (``n_steps`` overrides the step count for this call; ``init`` becomes the merged
        latents, i.e. a warm start).  Sequence ids are renumbered 0 … n−1.
        """
        self._check_fitted()
        Y_new, ids_new = as_sequences(sequences)
        check_array(Y_new, "new sequences", columns=self.n_features_in_)
        X_new = self.transform(Y_new)
        _, old = np.unique(self.sequence_ids_, return_inverse=True)  # ids become 0 … n−1
        ids = np.r_[old, ids_new + old.max() + 1]
        steps = self.n_steps
        self.set_params(init=np.vstack([self.latents_, X_new]), n_steps=steps if n_steps is None else n_steps)
        try:
            return self.fit(np.vstack([self.Y_, Y_new]), ids, callback=callback)
        finally:
            self.n_steps = steps

    # -- mapping and projection ----------------------------------------------------------------
    @property
    def kernel_(self):
        """The fitted latent :class:`~handflow.plugins.manifold.kernels.ProductKernel` (one kernel per dimension)."""
        self._check_fitted()
        return self._manifold.kernel

    def _check_fitted(self):
        check_is_fitted(self, "latents_", msg="this %(name)s is not fitted yet; call fit() or load() first")

    def inverse_transform(self, X):
        """f: latent (M, q) → observation (M, d); a single latent (q,) gives (d,)."""
        self._check_fitted()
        q = self.latents_.shape[1]
        X = np.asarray(X, dtype=float)
        single = X.ndim == 1 and X.shape == (q,)
        Xa = check_array(X[None, :] if single else X, "latents", columns=q)
        F = self._manifold.f(Xa)
        return F[0] if single else F

    def transform(self, Y, mask=None):
        """g: observation (M, d) → latent (M, q) by (masked) orthogonal projection (§7).

        ``mask``: per-dimension weights (d,) or (M, d) ≥ 0; weight 0 ignores a dimension
        (partial observation / associative completion).  A single observation (d,) gives (q,).
        """
        self._check_fitted()
        Y = np.asarray(Y, dtype=float)
        single = Y.ndim == 1
        Ya = check_array(Y[None, :] if single else Y, "Y", columns=self.n_features_in_)
        w = self._check_mask(mask, Ya.shape)
        X = self._manifold.project(Ya, w, n_iter=int(self.projection_steps))
        return X[0] if single else X

    def _check_mask(self, mask, shape):
        if mask is None:
            return None
        w = np.asarray(mask, dtype=float)
        if w.shape not in ((shape[1],), shape):
            raise InvalidInputError(f"mask must have shape ({shape[1]},) or {shape}, got {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w.sum(axis=-1) <= 0):
            raise InvalidInputError("mask weights must be finite, >= 0 and not all zero")
        return w

    def reconstruction_error(self, Y, mask=None):
        """``e_t = (y − f(g(y)))ᵀ Σ⁻¹ (y − f(g(y)))`` per row, Σ = diag(train_variance_)
        (recognition spec); with a mask, g is the masked projection and the sum runs over the
        weighted dimensions (weights multiply the terms)."""
        Y = np.asarray(Y, dtype=float)
        single = Y.ndim == 1
        Ya = Y[None, :] if single else Y
        X = self.transform(Ya, mask)
        r = Ya - self._manifold.f(X)
        w = 1.0 / self.train_variance_
        if mask is not None:
            w = w * np.asarray(mask, dtype=float)
        e = np.sum(r * r * w, axis=1)
        return e[0] if single else e

    def score(self, Y, mask=None):
        """Negative mean normalised reconstruction error (higher is better, sklearn style)."""
        return -float(np.mean(self.reconstruction_error(Y, mask)))

    # -- persistence ---------------------------------------------------------------------------
    def save(self, path, provenance=None):
        """Write ``.npz`` + JSON metadata (docs/training.md); see :mod:`handflow.plugins.manifold.io`."""
        self._check_fitted()
        save_model(self, path, provenance)

    @classmethod
    def load(cls, path):
        """Read a model written by :meth:`save`; unknown format versions are refused."""
        return load_model(cls, path)
