"""Competitive layer model with banded lateral compatibilities (docs/segmentation.md §B).

Layers ``α = 0…L−1`` hold one linear-threshold neuron per observation ``r = 0…N−1``.  The
lateral compatibility of layer ``α`` is a symmetric banded matrix given by its diagonal
``diag[α]`` and its band ``band[α, r, k − 1] = f^α(r, r + k)``, ``k = 1…B``: nothing outside
``|r − r'| ≤ B`` is stored or touched.

The solver is the annealed asynchronous Gauss–Seidel scheme of Wersing / Ontrup & Ritter: one
sweep is ``N·L`` updates of randomly chosen neurons

    x_rα ← max(0, (J h_r − I Σ_{β≠α} x_rβ + Σ_{r'≠r} f^α_rr' x_r'α) / (I − f^α_rr + T)),

each the exact minimiser of the annealed energy ``E_T = E + ½ T Σ x²`` in that coordinate, so
``E_T`` never increases at fixed ``T``.  After each sweep ``T ← η T``; the run stops when every
column has exactly one non-zero activity and no activity moved by more than ``tol`` (relative to
the largest activity).  Documented choice ("quench"): as soon as a sweep ends with a unique
assignment, ``T`` is set to 0, so the activities settle on the fixed point of the un-annealed
dynamics instead of tracking the slowly decaying temperature.  The inner loop is numba-compiled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy import sparse
from scipy.linalg import eigvals_banded
from scipy.linalg.lapack import dpbtrf
from scipy.sparse.linalg import ArpackError, eigsh
from sklearn.base import BaseEstimator


@numba.njit(cache=True, inline="always")
def _xorshift(state):  # pragma: no cover - compiled
    """xorshift64 step (Marsaglia): cheap, seedable, good enough to pick neurons."""
    state ^= (state << np.uint64(13)) & np.uint64(0xFFFFFFFFFFFFFFFF)
    state ^= state >> np.uint64(7)
    state ^= (state << np.uint64(17)) & np.uint64(0xFFFFFFFFFFFFFFFF)
    return state


@numba.njit(cache=True, nogil=True)
def _sweeps(x, colsum, band, diag, J, inhib, T, eta, max_sweeps, tol, seed, first):  # pragma: no cover - compiled
    """Run annealed sweeps in place over the columns ``first…N−1`` (the others are held fixed;
    ``T`` holds one temperature per column and is annealed in place too); returns (sweeps done,
    converged flag)."""
    state = np.uint64(seed) * np.uint64(2685821657736338717) + np.uint64(1)
    L, N = x.shape
    B = band.shape[2]
    M = N - first
    n_updates = M * L
    for sweep in range(1, max_sweeps + 1):
        max_change = 0.0
        for _ in range(n_updates):
            state = _xorshift(state)
            pick = state >> np.uint64(11)
            r = first + np.int64(pick % np.uint64(M))
            a = np.int64((pick // np.uint64(M)) % np.uint64(L))
            lat = 0.0
            for k in range(1, B + 1):
                if r + k < N:
                    lat += band[a, r, k - 1] * x[a, r + k]
                if r - k >= 0:
                    lat += band[a, r - k, k - 1] * x[a, r - k]
            old = x[a, r]
            num = J - inhib * (colsum[r] - old) + lat
            new = num / (inhib - diag[a] + T[r])
            if new < 0.0:
                new = 0.0
            x[a, r] = new
            colsum[r] += new - old
            change = abs(new - old)
            if change > max_change:
                max_change = change
        for r in range(first, N):
            T[r] *= eta
        unique = True
        xmax = 0.0
        for r in range(first, N):
            active = 0
            for a in range(L):
                if x[a, r] > 0.0:
                    active += 1
                if x[a, r] > xmax:
                    xmax = x[a, r]
            if active != 1:
                unique = False
        if unique:
            if max_change <= tol * xmax:
                return sweep, True
            T[first:] = 0.0  # quench: the assignment is unique, only the activities still settle
    return max_sweeps, False


LANCZOS_MIN_N = 200  # from this size on, the largest eigenvalue comes from Lanczos iterations
BISECTION_MIN_N = 2048  # ... and from this size on from bisection on Cholesky factorisations
BISECTION_RTOL = 1e-14  # the bisection's bracket, relative to the first bracket's scale


def largest_eigenvalue(band: np.ndarray, diag: float) -> float:
    """Largest eigenvalue of one symmetric banded compatibility matrix.

    Documented choice (docs/segmentation.md, documented choices): below ``LANCZOS_MIN_N``
    observations the LAPACK banded solver, whose reduction to tridiagonal form costs O(N²·B); up to
    ``BISECTION_MIN_N`` ARPACK's Lanczos iterations on the sparse banded matrix (relative tolerance
    1e-10); from there on bisection (:func:`_bisected_eigenvalue`), O(N·B²) per step whatever the
    spectrum — Lanczos needs ever more iterations where the top eigenvalues crowd together, as in a
    layer of near-constant compatibilities (12 s for 16 000 observations, against 0.08 s).
    """
    n, width = band.shape
    if n == 1 or not band.any():
        return float(diag)
    width = min(width, n - 1)
    if n >= BISECTION_MIN_N:
        return _bisected_eigenvalue(band[:, :width], float(diag))
    if n >= LANCZOS_MIN_N:
        offsets = np.r_[0, np.arange(1, width + 1), -np.arange(1, width + 1)]
        diagonals = [np.full(n, float(diag))] + [band[: n - k, k - 1] for k in range(1, width + 1)] * 2
        A = sparse.diags(diagonals, offsets, shape=(n, n), format="csr")
        try:  # deterministic start vector
            return float(eigsh(A, k=1, which="LA", tol=1e-10, v0=np.ones(n), return_eigenvectors=False)[0])
        except ArpackError:  # no convergence: the exact banded solver below
            pass
    lower = _lower_form(band[:, :width], diag)
    return float(eigvals_banded(lower, lower=True, select="i", select_range=(n - 1, n - 1))[0])


def _lower_form(band: np.ndarray, diag: float) -> np.ndarray:
    """The banded matrix in LAPACK's lower form: ``lower[k, i] = A[i + k, i]``."""
    lower = np.zeros((band.shape[1] + 1, band.shape[0]))
    lower[0] = diag
    lower[1:] = band.T
    return lower


def _bisected_eigenvalue(band: np.ndarray, diag: float) -> float:
    """λ_max of the banded matrix (``band`` (N, B), constant ``diag``) by bisection: ``σI − A`` has
    a Cholesky factorisation exactly when ``σ > λ_max``, so the bracket [``diag`` (the largest
    diagonal entry), Gershgorin's bound] halves per banded factorisation (LAPACK ``pbtrf``) down
    to ``BISECTION_RTOL`` of its first scale; returns the bracket's upper end."""
    lo, hi = diag, gershgorin_bound(band[None], np.array([diag]))
    tol = BISECTION_RTOL * max(abs(lo), abs(hi))
    shifted = -_lower_form(band, diag)  # σI − A, its diagonal set per σ
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        shifted[0] = mid - diag
        _, info = dpbtrf(shifted, lower=1)
        if info == 0:
            hi = mid
        else:
            lo = mid
    return float(hi)


def gershgorin_bound(band: np.ndarray, diag: np.ndarray) -> float:
    """Upper bound of the largest eigenvalue over all layers: max row sum of |f| (Gershgorin)."""
    a = np.abs(band)
    rows = a.sum(axis=2)
    for k in range(1, band.shape[2] + 1):
        rows[:, k:] += a[:, :-k, k - 1]
    return float((rows + diag[:, None]).max())


def clm_energy(
    x: np.ndarray, band: np.ndarray, diag: np.ndarray, J: float, inhibition: float, temperature: float = 0.0
) -> float:
    """``E_T = −J Σ x + ½ I Σ_r (Σ_α x_rα)² − ½ Σ_α x_αᵀ F^α x_α + ½ T Σ x²`` (h_r = 1)."""
    L, N, B = band.shape
    lateral = float(np.sum(diag * np.sum(x * x, axis=1)))
    for k in range(1, min(B, N - 1) + 1):
        lateral += 2.0 * float(np.sum(band[:, : N - k, k - 1] * x[:, : N - k] * x[:, k:]))
    colsum = x.sum(axis=0)
    return float(
        -J * x.sum() + 0.5 * inhibition * np.dot(colsum, colsum) - 0.5 * lateral + 0.5 * temperature * np.sum(x * x)
    )


@dataclass
class CLMResult:
    """Outcome of one CLM run: activities (L, N), winner layer per column (−1 if none), stats;
    ``temperature`` holds the final temperature of each column (N,)."""

    activities: np.ndarray
    winners: np.ndarray
    sweeps: int
    converged: bool
    energy: float
    inhibition: float
    temperature: np.ndarray


class CompetitiveLayerModel(BaseEstimator):
    """Annealed asynchronous Gauss–Seidel CLM solver over banded layer compatibilities.

    Parameters
    ----------
    J : float, default 2.0
        Input weight (input significance ``h_r = 1``).  Thesis: 2.
    inhibition : float or None, default None
        Columnar inhibition ``I``; ``None`` = documented choice
        ``I = inhibition_margin · max(λ_max, J/2)`` with λ_max the largest eigenvalue over all
        layers, which puts ``I`` above every layer's largest eigenvalue (columnar
        winner-take-all) and keeps ``I − f_rr > 0``.
    inhibition_margin : float, default 1.5
        Factor of the automatic inhibition (> 1).  1.5: within a winning group
        Gauss–Seidel contracts roughly by ``λ_max / I`` per sweep, so a margin of 1.1 needed
        ~100 sweeps to settle where 1.5 needs ~25–40 with the same labels on our letter data.
    eta : float, default 0.9
        Annealing factor per sweep, ``T ← η T``.
    temperature : float or None, default None
        Start temperature; ``None`` = largest eigenvalue (docs/segmentation.md step 1).
    tol : float, default 1e-3
        Relative activity-change tolerance of the convergence test.
    max_sweeps : int, default 1000
        Cap on sweeps (the result reports ``converged=False`` when hit).
    init_scale : float, default 0.01
        Initial activities are uniform in ``(0, init_scale)``.
    spectral : {'eigen', 'gershgorin'}, default 'eigen'
        How λ_max is obtained: ``"eigen"`` (exact, LAPACK banded solver) or
        ``"gershgorin"`` (the max absolute row sum, an upper bound that is ~10× cheaper; used by
        the online segmenter, where the exact value costs more than the sweeps).
    random_state : int, numpy.random.Generator or None, default None
        Seed or generator; the run is deterministic given a seed.
        The constructor only stores it (scikit-learn convention); the generator ``rng_`` is made
        from it at the first :meth:`solve` and advances over later runs (new ``random_state`` via
        ``set_params`` starts a new one).

    Attributes
    ----------
    rng_ : numpy.random.Generator
        The generator of the initial activities, made from ``random_state`` at the first run.

    It learns nothing, so it has no ``fit``: :meth:`solve` runs it on the layer compatibilities
    (docs/segmentation.md §B; the estimator test waives the fit checks, docs/architecture.md).

    Examples
    --------
    >>> import numpy as np
    >>> from handflow.plugins.segmenter.clm import CompetitiveLayerModel
    >>> band = np.zeros((2, 6, 2))  # 2 layers, 6 columns, compatibility with the next column
    >>> band[0, :2, 1] = band[1, 3:5, 1] = 1.0  # layer 0 binds columns 0-2, layer 1 columns 3-5
    >>> band[0, 3:5, 1] = band[1, :2, 1] = -1.0
    >>> result = CompetitiveLayerModel(random_state=1).solve(band, np.zeros(2))
    >>> result.winners.tolist()
    [0, 0, 0, 1, 1, 1]
    """

    def __init__(
        self,
        *,
        J: float = 2.0,
        inhibition: float | None = None,
        inhibition_margin: float = 1.5,
        eta: float = 0.9,
        temperature: float | None = None,
        tol: float = 1e-3,
        max_sweeps: int = 1000,
        init_scale: float = 0.01,
        spectral: str = "eigen",
        random_state=None,
    ) -> None:
        self.J = J
        self.inhibition = inhibition
        self.inhibition_margin = inhibition_margin
        self.eta = eta
        self.temperature = temperature
        self.tol = tol
        self.max_sweeps = max_sweeps
        self.init_scale = init_scale
        self.spectral = spectral
        self.random_state = random_state

    def set_params(self, **params):
        self.__dict__.pop("rng_", None)
        return super().set_params(**params)

    def _generator(self) -> np.random.Generator:
        if "rng_" not in self.__dict__:
            self.rng_ = np.random.default_rng(self.random_state)
        return self.rng_

    def _validate(self, band: np.ndarray, diag: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        band = np.ascontiguousarray(band, dtype=np.float64)
        diag = np.ascontiguousarray(diag, dtype=np.float64).reshape(-1)
        if band.ndim != 3 or band.shape[0] != diag.size:
            raise ValueError(
                f"band must be (layers, N, width) with one diagonal value per layer; "
                f"got band {band.shape} and {diag.size} diagonal values"
            )
        if not (np.isfinite(band).all() and np.isfinite(diag).all()):
            raise ValueError("compatibilities hold NaN/inf; check the candidate projections")
        if not 0.0 < self.eta <= 1.0:
            raise ValueError(f"eta must lie in (0, 1], got {self.eta}")
        return band, diag

    def spectral_scale(self, band: np.ndarray, diag: np.ndarray) -> float:
        """Largest eigenvalue over all layers (``spectral="eigen"``) or its Gershgorin bound."""
        if self.spectral == "gershgorin":
            return gershgorin_bound(band, diag)
        if self.spectral != "eigen":
            raise ValueError(f"spectral must be 'eigen' or 'gershgorin', got {self.spectral!r}")
        return max(largest_eigenvalue(band[a], diag[a]) for a in range(band.shape[0]))

    def initial_activities(self, shape: tuple[int, int]) -> np.ndarray:
        return self._generator().uniform(0.0, self.init_scale, size=shape) + 1e-12

    def start(
        self,
        band: np.ndarray,
        diag: np.ndarray,
        x0: np.ndarray | None = None,
        temperature: float | np.ndarray | None = None,
        lambda_max: float | None = None,
        eta: float | None = None,
        first: int = 0,
    ) -> CLMRun:
        """Set up a run from ``x0`` (default: small positive random values) without sweeping.

        ``temperature`` overrides the start temperature, one value or one per column (N,) (the
        online segmenter anneals each observation from its arrival, docs/segmentation.md §C);
        ``lambda_max`` may pass a precomputed largest eigenvalue; ``eta`` overrides the annealing
        factor of this run; only the columns from ``first`` on are updated (the others, from
        ``x0``, are a fixed context: the online segmenter's fast run).  The inhibition and the
        start temperature come from ``band`` (pass ``lambda_max`` for another scale).
        """
        band, diag = self._validate(band, diag)
        L, N, _ = band.shape
        lam = self.spectral_scale(band, diag) if lambda_max is None else float(lambda_max)
        inhib = self.inhibition if self.inhibition is not None else self.inhibition_margin * max(lam, 0.5 * self.J)
        if inhib <= diag.max():
            raise ValueError(f"inhibition I={inhib} must exceed every self-excitation (max {diag.max()})")
        if temperature is None:
            temperature = self.temperature if self.temperature is not None else max(lam, 0.0)
        x = self.initial_activities((L, N)) if x0 is None else np.array(x0, dtype=np.float64, order="C")
        if x.shape != (L, N):
            raise ValueError(f"x0 must have shape {(L, N)}, got {x.shape}")
        T = np.array(np.broadcast_to(np.asarray(temperature, dtype=np.float64), (N,)))
        if not 0 <= first < N:
            raise ValueError(f"first must lie in 0…{N - 1}, got {first}")
        return CLMRun(self, band, diag, x, T, float(inhib), float(self.eta if eta is None else eta), int(first))

    def solve(
        self,
        band: np.ndarray,
        diag: np.ndarray,
        x0: np.ndarray | None = None,
        temperature: float | np.ndarray | None = None,
        lambda_max: float | None = None,
    ) -> CLMResult:
        """Run the dynamics to convergence (or ``max_sweeps``); arguments as :meth:`start`."""
        run = self.start(band, diag, x0, temperature, lambda_max)
        run.advance(self.max_sweeps)
        return run.result()


class CLMRun:
    """One CLM run advanced a given number of sweeps at a time (:meth:`CompetitiveLayerModel.start`).

    Documented choice (docs/segmentation.md §C): the online segmenter spreads a window-wide solve
    over several updates this way; :meth:`CompetitiveLayerModel.solve` advances it in one go.
    The run ends when it converged or used the solver's ``max_sweeps``.
    """

    def __init__(self, solver: CompetitiveLayerModel, band, diag, x, T, inhibition: float, eta: float, first: int):
        self.solver, self.band, self.diag, self.x, self.T = solver, band, diag, x, T
        self.inhibition, self.eta, self.first = inhibition, eta, first
        self.colsum = x.sum(axis=0)
        self.sweeps = 0
        self.converged = False

    @property
    def finished(self) -> bool:
        return self.converged or self.sweeps >= self.solver.max_sweeps

    def advance(self, sweeps: int) -> bool:
        """Run up to ``sweeps`` more sweeps (within the solver's cap); returns :attr:`finished`."""
        budget = min(int(sweeps), int(self.solver.max_sweeps) - self.sweeps)
        if self.converged or budget <= 0:
            return self.finished
        s = self.solver
        seed = int(s._generator().integers(0, 2**31 - 1))
        done, self.converged = _sweeps(
            self.x,
            self.colsum,
            self.band,
            self.diag,
            float(s.J),
            self.inhibition,
            self.T,
            self.eta,
            budget,
            float(s.tol),
            seed,
            self.first,
        )
        self.sweeps += int(done)
        return self.finished

    def result(self, energy: bool = True) -> CLMResult:
        """The run's current state (``energy=False`` skips the energy, reported as NaN)."""
        x = self.x
        winners = np.where(x.max(axis=0) > 0.0, x.argmax(axis=0), -1)
        return CLMResult(
            activities=x,
            winners=winners,
            sweeps=self.sweeps,
            converged=bool(self.converged),
            energy=clm_energy(x, self.band, self.diag, self.solver.J, self.inhibition) if energy else float("nan"),
            inhibition=self.inhibition,
            temperature=self.T,
        )
