"""Every ``.npz`` file a node or command loads — UKR models and class models, manipulation
manifolds, grasp SOMs and grasp datasets, recognition datasets and training data — loads, or is
refused with a ``ValueError`` that names the file, whatever was done to it: truncated, bytes
changed, metadata or arrays garbled (handflow.framework.files.npz, docs/robustness.md).  Scorer
files have their own tests."""

from __future__ import annotations

import io
import json
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handflow.framework.files.npz import NpzFileError, building, npz_metadata, read_npz
from handflow.plugins.grasp.experience import ExperienceBase, GraspDataset
from handflow.plugins.grasp.som import load_som
from handflow.plugins.manifold.data import load_npz
from handflow.plugins.manifold.model import StructuredUKR
from handflow.plugins.manipulation.manifold_file import ManipulationManifold
from handflow.plugins.segmenter.datasets import basicmotions_continuous, load_dataset, load_recordings
from handflow.plugins.segmenter.models import load_candidates
from tests.garbage import damaged_file

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def _use_ukr(model) -> None:
    model.transform(model.Y_[:2])


def _use_som(path) -> None:
    som, _ = load_som(path)
    som.best_match(som.nodes_.reshape(-1, som.n_features_in_)[:2])


_RNG = np.random.default_rng(0)
CONTINUOUS = {
    "class_names": np.array(["a", "b"]),
    **{f"X_r{k}": _RNG.normal(size=(40, 3)) for k in range(2)},
    **{f"y_r{k}": np.repeat([0, 1], 20) for k in range(2)},
}
UEA = {  # 8 cases: enough for the 8 recordings of basicmotions_continuous
    "X_train": _RNG.normal(size=(6, 2, 30)),
    "X_test": _RNG.normal(size=(2, 2, 30)),
    "labels_train": np.array([0, 1, 0, 1, 0, 1]),
    "labels_test": np.array([0, 1]),
    "class_names": np.array(["a", "b"]),
}
LOADERS = {
    "ukr": (CONFIGS / "models/gestures/grasp.npz", lambda p: _use_ukr(StructuredUKR.load(p))),
    "class_models": (CONFIGS / "models/gestures/grasp.npz", lambda p: load_candidates([p])),
    "manipulation": (
        CONFIGS / "models/cap_constructed.npz",
        lambda p: ManipulationManifold.load(p).posture([0.5, 2.5]),
    ),
    "som": (CONFIGS / "grasp/experience_hard/som_box.npz", _use_som),
    "dataset": (CONFIGS / "grasp/experience_hard/grasps.npz", GraspDataset.load),
    "experience": (CONFIGS / "grasp/experience_hard/som_box.npz", ExperienceBase.load),
    "continuous_dataset": (CONTINUOUS, load_recordings),
    "uea_dataset": (UEA, load_dataset),
    "uea_continuous": (UEA, basicmotions_continuous),
    "training_data": ({"seq_a": _RNG.normal(size=(20, 3)), "seq_b": _RNG.normal(size=(15, 3))}, load_npz),
}
WITH_METADATA = [kind for kind, (source, _) in LOADERS.items() if isinstance(source, Path)]
FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda kids: st.lists(kids, max_size=3) | st.dictionaries(st.text(max_size=5), kids, max_size=3),
    max_leaves=8,
)


def _loads_or_refuses(kind: str, path: Path) -> None:
    """The loader (and a first use of what it loaded) succeeds or raises a ValueError naming the file."""
    try:
        LOADERS[kind][1](path)
    except ValueError as exc:
        assert path.name in str(exc), exc


def _arrays(kind: str) -> dict[str, np.ndarray]:
    source = LOADERS[kind][0]
    if isinstance(source, dict):
        return dict(source)
    with np.load(source, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


def _file_bytes(kind: str) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **_arrays(kind))
    return buffer.getvalue()


def _written(kind: str, tmp_path: Path) -> Path:
    path = tmp_path / f"{kind}.npz"
    path.write_bytes(_file_bytes(kind))
    return path


@pytest.mark.parametrize("kind", LOADERS)
def test_intact_files_load(kind, tmp_path):
    LOADERS[kind][1](_written(kind, tmp_path))


@pytest.mark.parametrize("kind", LOADERS)
@FUZZ
@given(data=st.data())
def test_truncated_or_byte_edited_files_load_or_are_refused(kind, tmp_path, data):
    bad = tmp_path / "mutated.npz"
    bad.write_bytes(damaged_file(data.draw, _file_bytes(kind)))
    _loads_or_refuses(kind, bad)


@pytest.mark.parametrize("kind", WITH_METADATA)
@FUZZ
@given(data=st.data(), value=JSON)
def test_garbled_metadata_loads_or_is_refused(kind, tmp_path, data, value):
    """One metadata entry (top level, or inside a nested object) replaced by arbitrary JSON."""
    arrays = _arrays(kind)
    meta = json.loads(str(arrays["metadata"][()]))
    target = meta
    while True:
        key = data.draw(st.sampled_from(sorted(target)))
        if isinstance(target[key], dict) and target[key] and data.draw(st.booleans()):
            target = target[key]
            continue
        target[key] = value
        break
    arrays["metadata"] = np.array(json.dumps(meta))
    bad = tmp_path / "garbled.npz"
    np.savez(bad, **arrays)
    _loads_or_refuses(kind, bad)


@pytest.mark.parametrize("kind", LOADERS)
@FUZZ
@given(
    data=st.data(),
    replacement=st.sampled_from(
        [np.zeros(0), np.zeros((2, 2)), np.full((3, 1, 2), np.nan), np.array(["x"]), np.arange(5), np.float64(1.0)]
    ),
)
def test_replaced_or_missing_arrays_load_or_are_refused(kind, tmp_path, data, replacement):
    arrays = _arrays(kind)
    name = data.draw(st.sampled_from(sorted(set(arrays) - {"metadata"})))
    if data.draw(st.booleans()):
        del arrays[name]
    else:
        arrays[name] = replacement
    bad = tmp_path / "arrays.npz"
    np.savez(bad, **arrays)
    _loads_or_refuses(kind, bad)


@FUZZ
@given(content=st.one_of(JSON.map(json.dumps), st.text(max_size=20)))
def test_a_garbled_class_index_is_refused_naming_it(tmp_path, content):
    (tmp_path / "classes.json").write_text(content)
    try:
        load_candidates(tmp_path)
    except (ValueError, FileNotFoundError) as exc:  # FileNotFoundError: it lists files that are not there
        assert str(tmp_path) in str(exc), exc


def test_the_reader_names_the_file_and_what_to_do(tmp_path):
    with pytest.raises(NpzFileError, match=r"none\.npz: no such model file; train it"):
        read_npz(tmp_path / "none.npz", "model", "train it")
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(
        NpzFileError, match=r"not a model file: that is an \.npz archive .*starts with b'hell'; train it"
    ) as e:
        read_npz(tmp_path / "text.npz", "model", "train it")  # numpy would take a non-zip file for a pickle
    assert "pickle" not in str(e.value)
    # an .npy header cut inside its dictionary: numpy's reader raises tokenize.TokenError
    header = b"{'descr': '<f8', 'fortran_order': False, 'shape': (3,"
    header += b" " * (53 - len(header)) + b"\n"
    with zipfile.ZipFile(tmp_path / "header.npz", "w") as z:
        z.writestr("metadata.npy", b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header + bytes(24))
    with pytest.raises(NpzFileError, match="not a readable model file"):
        read_npz(tmp_path / "header.npz", "model", "train it")
    np.savez(tmp_path / "list.npz", metadata=np.array("[1, 2]"))
    with pytest.raises(NpzFileError, match="metadata is not a JSON object"):
        npz_metadata(read_npz(tmp_path / "list.npz", "model", "train it"), "list.npz", "model", "train it")
    np.savez(tmp_path / "v2.npz", metadata=np.array(json.dumps({"format": "m", "format_version": 2})))
    arrays = read_npz(tmp_path / "v2.npz", "model", "train it")
    fmt = ("m", 1, "format_version")
    with pytest.raises(NpzFileError, match="model file format version 2, this handflow reads version 1; train it"):
        npz_metadata(arrays, "v2.npz", "model", "train it", fmt=fmt)
    with pytest.raises(NpzFileError, match=r"not a handflow other file \(format 'm'\); train it"):
        npz_metadata(arrays, "v2.npz", "other", "train it", fmt=("o", 2, "format_version"))
    with pytest.raises(NpzFileError, match=r"inconsistent model file \(KeyError: 'params'\); train it"):
        with building("m.npz", "model", "train it"):
            {}["params"]
