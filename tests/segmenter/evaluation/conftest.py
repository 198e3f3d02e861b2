import numpy as np
import pytest

from tests.segmenter.datasets.test_recordings import _synthetic_recordings


def _npz(tmp_path_factory, recordings: int):
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(recordings):
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = _synthetic_recordings(k)
    path = tmp_path_factory.mktemp("three_classes") / "s.npz"
    np.savez(path, **arrays)
    return path


@pytest.fixture(scope="session")
def three_class_npz(tmp_path_factory):
    """A continuous .npz of four synthetic recordings of three motion classes in random order."""
    return _npz(tmp_path_factory, 4)


@pytest.fixture(scope="session")
def three_recordings_npz(tmp_path_factory):
    """The first three recordings of :func:`three_class_npz`: the fewest the protocol takes (three
    folds of two inner folds each, half the fits of four recordings), for the evaluations whose
    assertions do not depend on the data."""
    return _npz(tmp_path_factory, 3)
