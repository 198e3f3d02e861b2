import json
from pathlib import Path

import numpy as np
import pytest

from handflow.plugins.segmenter import DatasetError, LetterGenerator, load_dataset
from handflow.plugins.segmenter.datasets import split_counts

LETTERS = Path("/work/shared/data/letters_other_xy.npz")
BASIC = Path("/work/shared/data/basicmotions.npz")


def write_csv_dataset(root: Path, ds) -> Path:
    for split in ("train", "validation", "test"):
        (root / split).mkdir(parents=True)
        for k, t in enumerate(ds.split(split)):
            rows = np.column_stack([np.arange(len(t.data)) * 0.01, t.data])
            np.savetxt(root / split / f"{t.label}_{k}.csv", rows, delimiter=",", header="time,x,y", comments="")
    return root


def test_csv_folder_round_trip_drops_the_time_column(tmp_path):
    ds = LetterGenerator(n_classes=2, random_state=0).dataset((2, 1, 1))
    loaded = load_dataset(write_csv_dataset(tmp_path / "d", ds))
    assert loaded.classes == ["A", "B"] and loaded.columns == ["x", "y"]
    assert len(loaded.train) == 4 and len(loaded.test) == 2
    np.testing.assert_allclose(loaded.train[0].data, ds.train[0].data, atol=1e-12)


def test_csv_rows_are_sorted_by_time(tmp_path):
    for s in ("train", "validation", "test"):
        (tmp_path / s).mkdir()
        (tmp_path / s / "a_1.csv").write_text("t,v1,v2\n2,20,0\n1,10,0\n3,30,0\n")
    assert load_dataset(tmp_path).train[0].data[:, 0].tolist() == [10, 20, 30]


def test_folder_errors_say_what_to_change(tmp_path):
    (tmp_path / "train").mkdir()
    with pytest.raises(DatasetError, match="validation"):
        load_dataset(tmp_path)
    with pytest.raises(DatasetError, match="does not exist"):
        load_dataset(tmp_path / "nope")
    for s in ("validation", "test"):
        (tmp_path / s).mkdir()
    (tmp_path / "train" / "a_1.csv").write_text("x,y\n1,oops\n")
    with pytest.raises(DatasetError, match="non-numeric"):
        load_dataset(tmp_path)


def test_labelled_npz_uses_the_documented_split(tmp_path):
    rng = np.random.default_rng(0)
    arrays = {f"{c}_{k}": rng.normal(size=(20, 2)) for c in "ab" for k in range(5)}
    meta = {"samples": {"a_0": {"pen_lift_start": 15}}}
    np.savez(tmp_path / "d.npz", metadata=np.array(json.dumps(meta)), **arrays)
    ds = load_dataset(tmp_path / "d.npz")
    assert [t.name for t in ds.test] == ["a_4", "b_4"] and [t.name for t in ds.validation] == ["a_3", "b_3"]
    assert len(ds.train[0].data) == 15  # pen-lift tail cut
    assert len(load_dataset(tmp_path / "d.npz", trim_pen_lift=False).train[0].data) == 20
    assert split_counts(15) == (5, 5, 5) and split_counts(5) == (3, 1, 1)
    with pytest.raises(DatasetError, match="at least 3"):
        split_counts(2)


@pytest.mark.skipif(not LETTERS.exists(), reason="shared letters data not present")
def test_real_letters_load():
    ds = load_dataset(LETTERS)
    assert len(ds.classes) == 16 and len(ds.train) == 48 and len(ds.test) == 16


@pytest.mark.skipif(not BASIC.exists(), reason="shared BasicMotions data not present")
def test_basicmotions_loads_as_uea():
    ds = load_dataset(BASIC)
    assert ds.classes == ["Badminton", "Running", "Standing", "Walking"]
    assert ds.train[0].data.shape == (100, 6) and len(ds.validation) == 20 and len(ds.test) == 40
