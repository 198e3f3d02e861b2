"""One estimator style for the science classes (docs/architecture.md, "Estimator style").

Every estimator: keyword-only hyper-parameters, ``__init__`` stores only, randomness from
``random_state`` drawn in ``fit``, ``NotFittedError`` naming ``fit`` before fitting, and
``get_params``/``set_params``/``clone`` round trips.
"""

import inspect
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from handflow.plugins.grasp.som import SOM
from handflow.plugins.manifold import StructuredUKR
from handflow.plugins.segmenter.features import RunningStandardizer
from handflow.plugins.segmenter.scorers import PerClassHMM, SlidingDTW1NN
from tests.manifold.ukr_helpers import RING_LATENT, closed_curves


def _classes(seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4 * np.pi, 40)
    return {
        "a": [np.c_[np.sin(t), np.cos(t)] + rng.normal(0, 0.05, (40, 2)) for _ in range(2)],
        "b": [np.c_[np.sin(2 * t), t / t.max()] + rng.normal(0, 0.05, (40, 2)) for _ in range(2)],
    }


@dataclass
class Case:
    make: Callable  # keyword arguments -> unfitted estimator
    data: Callable  # () -> fit argument
    use: Callable  # (fitted, data) -> array result
    invalid: dict  # a hyper-parameter value that only fit may reject
    tweak: dict  # a valid set_params change


CASES = {
    "StructuredUKR": Case(
        lambda **kw: StructuredUKR(**{"latent": RING_LATENT, "n_steps": 5, "init": "equidistant", **kw}),
        lambda: closed_curves(n_seq=2, noise=0.02),
        lambda m, d: m.transform(np.vstack(d)),
        {"optimizer": "no-such-optimizer"},
        {"n_steps": 3},
    ),
    "SOM": Case(
        lambda **kw: SOM(**{"rows": 3, "cols": 4, "epochs": 3, "init": "random", **kw}),
        lambda: np.random.default_rng(1).normal(size=(30, 3)),
        lambda m, d: m.transform(d),
        {"mode": "no-such-mode"},
        {"epochs": 2},
    ),
    "SlidingDTW1NN": Case(
        lambda **kw: SlidingDTW1NN(**{"window": 5, **kw}),
        _classes,
        lambda m, d: m.scores(d["a"][0]),
        {"window": 0},
        {"threshold": -1.0},
    ),
    "PerClassHMM": Case(
        lambda **kw: PerClassHMM(**{"n_states": 2, "n_iter": 5, "window": 5, **kw}),
        _classes,
        lambda m, d: m.scores(d["a"][0]),
        {"n_states": 0},
        {"window": 4},
    ),
    "RunningStandardizer": Case(
        lambda **kw: RunningStandardizer(**kw),
        lambda: np.random.default_rng(2).normal(size=(30, 3)),
        lambda m, d: m.transform(d),
        {"prior_frames": 0},
        {"variance_floor": 0.05},
    ),
}
RANDOM = {"StructuredUKR", "SOM", "PerClassHMM"}


@pytest.fixture(params=sorted(CASES))
def case(request):
    if request.param == "PerClassHMM":
        pytest.importorskip("hmmlearn")
    return request.param, CASES[request.param]


def test_hyper_parameters_are_keyword_only(case):
    _, c = case
    est = c.make()
    params = list(inspect.signature(type(est).__init__).parameters.values())[1:]
    assert params and all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params)
    with pytest.raises(TypeError):
        type(est)(next(iter(est.get_params().values())))


def test_clone_and_set_params_round_trip(case):
    _, c = case
    est = c.make()
    twin = clone(est)
    assert twin is not est and twin.get_params() == est.get_params()
    ((key, value),) = c.tweak.items()
    assert est.set_params(**c.tweak) is est and est.get_params()[key] == value
    assert clone(est).get_params()[key] == value


def test_unfitted_call_raises_not_fitted_naming_fit(case):
    _, c = case
    with pytest.raises(NotFittedError, match="fit"):
        c.use(c.make(), c.data())


def test_constructor_does_no_work(case):
    _, c = case
    est = c.make(**c.invalid)  # stored, not checked
    ((key, value),) = c.invalid.items()
    assert est.get_params()[key] == value
    with pytest.raises(ValueError):
        est.fit(c.data())


def test_same_int_random_state_gives_identical_fits(case):
    name, c = case
    kw = {"random_state": 7} if name in RANDOM else {}
    data = c.data()
    a, b = c.make(**kw).fit(data), c.make(**kw).fit(data)
    np.testing.assert_array_equal(c.use(a, data), c.use(b, data))
    assert c.make(**kw).get_params() == c.make(**kw).get_params()
