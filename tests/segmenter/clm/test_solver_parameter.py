"""The CLM segmenter takes its solver as a parameter; the six solver keywords it once copied still
work for one release, with a DeprecationWarning (plugins/segmenter/clm/_segmenter.py)."""

import pytest
from sklearn.base import clone

from handflow.plugins.segmenter import CLMSegmenter, CompetitiveLayerModel, OnlineCLMSegmenter
from handflow.plugins.segmenter.clm import default_solver


def test_the_solver_is_a_parameter_and_runs_seeded_by_the_segmenter(candidates):
    solver = CompetitiveLayerModel(J=3.0, eta=0.95, max_sweeps=200, random_state=7)
    seg = CLMSegmenter(candidates, solver=solver, random_state=1)
    assert seg.get_params()["solver"] is solver and clone(seg).get_params()["solver__J"] == 3.0
    made = seg._solver()
    assert made is not solver and (made.J, made.eta, made.max_sweeps, made.random_state) == (3.0, 0.95, 200, 1)


def test_the_old_solver_keywords_warn_and_set_the_solver(candidates):
    with pytest.warns(DeprecationWarning, match=r"\['eta', 'max_sweeps'\].*solver="):
        old = CLMSegmenter(candidates, eta=1.0, max_sweeps=300, random_state=0)
    assert old.solver.get_params() == default_solver(candidates, eta=1.0, max_sweeps=300).get_params()
    with pytest.warns(DeprecationWarning):
        online = OnlineCLMSegmenter(candidates, window=60, block=20, max_sweeps=300, eta=1.0, random_state=0)
    assert online.solver.spectral == "gershgorin" and online.block_sweeps == 15
    with pytest.raises(TypeError, match="unexpected keyword arguments \\['J2'\\]"):
        CLMSegmenter(candidates, J2=1.0)


def test_a_solver_that_is_no_clm_is_refused(candidates):
    with pytest.raises(ValueError, match="solver must be a CompetitiveLayerModel"):
        CLMSegmenter(candidates, solver="fast")._solver()
