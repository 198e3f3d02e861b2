import numpy as np
import pytest

from tests.segmenter.datasets.test_recordings import _synthetic_recordings


@pytest.fixture(scope="session")
def three_class_npz(tmp_path_factory):
    """A continuous .npz of four synthetic recordings of three motion classes in random order."""
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(4):
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = _synthetic_recordings(k)
    path = tmp_path_factory.mktemp("three_classes") / "s.npz"
    np.savez(path, **arrays)
    return path
