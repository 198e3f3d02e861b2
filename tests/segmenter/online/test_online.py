import numpy as np

from handflow.plugins.segmenter import CLMSegmenter, OnlineCLMSegmenter
from handflow.plugins.segmenter.clm import default_solver
from handflow.plugins.segmenter.models import Projection


def stream(seg, proj):
    return [seg.update_projected(proj.latent_time[i], proj.errors[i]) for i in range(len(proj))]


def test_final_online_labels_equal_the_whole_stream_batch(candidates, synthetic):
    """The issue's agreement: each observation's final published label (node code path, the
    recording ends with finish) equals the whole-stream batch label; the stream spans several
    windows so block runs, not one window solve, make the final labels."""
    order = "ABCADBCDAB"
    pool = synthetic.test + synthetic.validation
    Y = np.vstack([next(t.data for t in pool[k % 2 :] if t.label == c) for k, c in enumerate(order)])
    assert len(Y) > 3 * 200
    online = OnlineCLMSegmenter(candidates, window=200, history=10, random_state=0).replay(Y)
    batch = CLMSegmenter(candidates, history=10, random_state=0).fit_predict(Y)
    assert np.mean(online == batch) >= 0.98
    # without the block runs the final labels are the fast run's: fewer agree
    fast_only = OnlineCLMSegmenter(candidates, window=200, history=10, block=0, random_state=0).replay(Y)
    assert np.mean(fast_only == batch) < np.mean(online == batch)


def test_block_runs_spread_the_sweep_cap_over_a_block_by_default(candidates, two_letters):
    """A block run that uses the solver's whole sweep budget must end before the next is due, so
    that no update has to finish a run at once: by default the cap is spread over the block."""
    assert OnlineCLMSegmenter(candidates, window=200, block=50).block_sweeps == 20
    solver = default_solver(candidates, max_sweeps=300, eta=1.0, spectral=OnlineCLMSegmenter.SPECTRAL)
    seg = OnlineCLMSegmenter(candidates, window=60, block=20, solver=solver, random_state=0)
    assert seg.block_sweeps == 15
    Y, _ = two_letters
    proj = candidates.project(Y[:100])
    sweeps = []
    for i in range(len(proj)):
        run = seg._run
        before = None if run is None else run[2].sweeps
        seg.update_projected(proj.latent_time[i], proj.errors[i])
        if run is not None and before is not None:
            sweeps.append(run[2].sweeps - before)
    assert sweeps and max(sweeps) <= 15  # never finished at once: η = 1 never converges early


def test_incremental_bands_equal_batch_bands(candidates, two_letters):
    Y, _ = two_letters
    proj = candidates.project(Y)
    online = OnlineCLMSegmenter(candidates, window=50, history=7, random_state=0)
    stream(online, proj)
    batch = CLMSegmenter(candidates, history=7)
    cand, _ = batch.layer_compatibilities(proj.take(slice(online.window_start, None)))
    band, diag = batch.with_background(cand[:-1], length=len(Y))  # λ_bg of the stream so far
    ob, od = online.layers()
    np.testing.assert_allclose(ob, band, atol=1e-12)
    np.testing.assert_allclose(od, diag)


def test_incremental_bands_bridge_projection_spikes_as_the_batch_does(candidates, two_letters):
    """A spike is bridged only once the next observation is known: the online bands then match the
    whole-stream batch bands, the observation before the window included."""
    Y, _ = two_letters
    proj = candidates.project(Y)
    spiked = proj.latent_time.copy()
    spiked[5::37] = np.mod(spiked[5::37] + 0.5 * np.pi, np.pi)  # one-observation spikes …
    spiked[20::37] = spiked[21::37] = np.mod(spiked[20::37] + 0.5 * np.pi, np.pi)  # … and two-observation ones
    proj = Projection(spiked, proj.errors, proj.classes)
    online = OnlineCLMSegmenter(candidates, window=50, history=7, random_state=0)
    stream(online, proj)
    cand, _ = CLMSegmenter(candidates, history=7).layer_compatibilities(proj)
    np.testing.assert_allclose(online.layers()[0][:-1], cand[:-1, online.window_start :], atol=1e-12)


def test_fast_run_over_the_tail_labels_a_continuing_motion(candidates, synthetic):
    Y = np.vstack([t.data for t in synthetic.test + synthetic.validation if t.label == "A"])
    proj = candidates.project(Y)
    seg = OnlineCLMSegmenter(candidates, window=200, history=10, random_state=0)
    ups = stream(seg, proj)
    assert max(u.sweeps for u in ups) <= seg.update_sweeps
    assert np.mean([u.label == 0 for u in ups[20:]]) > 0.75  # labels on arrival (no later context)
    assert np.mean(seg.window_labels == 0) > 0.95  # after block runs and revisions


def test_events_report_segments_and_revisions(candidates, two_letters):
    Y, truth = two_letters
    proj = candidates.project(Y)
    seg = OnlineCLMSegmenter(candidates, window=200, history=10, random_state=0)
    events = [e for u in stream(seg, proj) for e in u.events]
    starts = [e for e in events if e.kind == "start"]
    assert starts[0].start == 0
    assert any(e.label == 1 for e in starts)  # the second letter was announced
    b_start = next(e.start for e in starts if e.label == 1)
    assert abs(b_start - int(np.argmax(truth == 1))) <= 15
    for e in events:
        if e.kind == "revision":
            assert e.previous != e.label and e.start <= e.end
    assert np.mean(seg.window_labels == truth) > 0.9


def test_segment_tracker_moves_boundaries_on_revision():
    from handflow.plugins.segmenter.online import SegmentTracker

    tr = SegmentTracker()
    for i, lab in enumerate([0, 0, 0, 0, 1, 1, 1]):
        tr.update(i, lab)
    moved = tr.revise(2, 3, 1)  # the B segment really started at 2
    assert [(e.kind, e.label, e.start, e.end) for e in moved] == [("end", 0, 0, 1), ("start", 1, 2, 2)]
    assert tr.current == (1, 2)
    moved = tr.revise(4, 4, -1)  # a rejected point inside the B segment splits it
    assert [(e.kind, e.label, e.start, e.end) for e in moved] == [
        ("end", 1, 2, 3),
        ("start", -1, 4, 4),
        ("end", -1, 4, 4),
        ("start", 1, 5, 5),
    ]
    assert tr.current == (1, 5)


def test_revisions_need_confirmation_and_are_mostly_right(candidates, two_letters):
    Y, truth = two_letters
    proj = candidates.project(Y)
    counts = {}
    for confirm in (1, 5):
        seg = OnlineCLMSegmenter(
            candidates, window=200, history=10, confirm=confirm, edge=0 if confirm == 1 else None, random_state=0
        )
        revs = [e for u in stream(seg, proj) for e in u.events if e.kind == "revision"]
        counts[confirm] = len(revs)
        if confirm == 5:
            right = sum(int(np.sum(truth[e.start : e.end + 1] == e.label)) for e in revs)
            wrong = sum(int(np.sum(truth[e.start : e.end + 1] == e.previous)) for e in revs)
            assert right > 2 * wrong
            # every published label equals the current one unless its change is still unconfirmed
            assert np.mean(seg.published_labels == seg.window_labels) > 0.95
    assert counts[5] < counts[1]
