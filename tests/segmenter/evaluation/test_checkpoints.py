"""``--checkpoints``: every finished fold is kept, and a later run with the same recordings and
settings takes it from there instead of computing it; anything else is computed again
(plugins/segmenter/evaluation/_checkpoints.py, docs/segmentation.md)."""

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.plugins.segmenter.cli import register_evaluate
from handflow.plugins.segmenter.datasets import load_recordings
from handflow.plugins.segmenter.evaluation import RecordingsEvaluator
from handflow.plugins.segmenter.evaluation._checkpoints import FoldCheckpoints
from tests.conftest import run_command

ARGS = ["--methods", "dtw_1nn", "--quick", "--json", "--jobs", "1", "--normalise", "training", "--derived", "none"]


def _run(capsys, three_class_npz, *extra) -> tuple[dict, str]:
    assert run_command(register_evaluate, [str(three_class_npz), *ARGS, *extra]) == 0
    out = capsys.readouterr()
    result = json.loads(out.out)
    result.pop("runtime_s"), result.pop("timing")  # wall times: the machine's, not the figures
    return result, out.err


def test_a_resumed_evaluation_takes_the_kept_folds_and_reports_the_same(three_class_npz, tmp_path, capsys):
    plain, _ = _run(capsys, three_class_npz)
    kept = tmp_path / "folds"
    first, err = _run(capsys, three_class_npz, "--checkpoints", str(kept))
    assert first == plain and sorted(p.name for p in kept.iterdir()) == [f"fold-r{k}.npz" for k in range(4)]
    (kept / "fold-r2.npz").unlink()  # as if the run had stopped during that fold
    resumed, err = _run(capsys, three_class_npz, "--checkpoints", str(kept))
    assert resumed == plain
    assert [f"fold 'r{k}' taken from" in err for k in range(4)] == [True, True, False, True]
    assert err.count("holding out") == 1 and "holding out 'r2'" in err


def test_folds_of_other_settings_or_garbled_files_are_computed_again(three_class_npz, tmp_path, capsys):
    kept = tmp_path / "folds"
    _run(capsys, three_class_npz, "--checkpoints", str(kept))
    other, err = _run(capsys, three_class_npz, "--checkpoints", str(kept), "--lag", "2")
    assert err.count("a fold of other recordings, settings or code") == 4
    assert err.count("holding out") == 4 and other["parameters"]["lag"] == 2
    path = kept / "fold-r1.npz"
    path.write_bytes(path.read_bytes()[:100])  # truncated
    again, err = _run(capsys, three_class_npz, "--checkpoints", str(kept), "--lag", "2")
    assert again == other
    assert "not a readable evaluation fold file" in err and err.count("holding out") == 1


@pytest.fixture(scope="module")
def kept_fold(three_class_npz, tmp_path_factory) -> tuple[FoldCheckpoints, bytes]:
    """The store of one evaluation and the file of its first fold."""
    ev = RecordingsEvaluator(
        load_recordings(three_class_npz), methods=("dtw_1nn",), quick=True, checkpoints=tmp_path_factory.mktemp("kept")
    )
    store = ev._checkpoints()
    store.save(ev.run_fold("r0"))
    return store, store.path("r0").read_bytes()


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_no_mutation_of_a_kept_fold_crashes_the_evaluation(kept_fold, tmp_path_factory, data):
    """Any bytes flipped, dropped or added give either a fold of that recording or a recomputation."""
    store, good = kept_fold
    raw = bytearray(good)
    at = data.draw(st.integers(0, len(raw) - 1))
    action = data.draw(st.sampled_from(["flip", "drop", "insert"]))
    if action == "flip":
        raw[at] ^= data.draw(st.integers(1, 255))
    elif action == "drop":
        del raw[at : at + data.draw(st.integers(1, 64))]
    else:
        raw[at:at] = data.draw(st.binary(min_size=1, max_size=16))
    mutated = FoldCheckpoints(tmp_path_factory.mktemp("mutated"), store.digest, store.fold_type, lambda msg: None)
    mutated.path("r0").write_bytes(bytes(raw))
    fold = mutated.load("r0")
    assert fold is None or fold.recording == "r0"
