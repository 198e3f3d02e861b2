"""Drop accounting of a node's inputs: counts, rate-limited log, dropped events (docs/robustness.md)."""

from __future__ import annotations

import logging

from handflow.framework.runtime.drops import DropLedger


def test_counts_rate_limits_the_log_and_reports_each_drop_once(caplog):
    log = logging.getLogger("handflow.node.human")
    ledger = DropLedger("human", {"raw": "handflow/g/glove/frames", "aux": "handflow/g/x/y"}, log, log_interval_s=60)
    with caplog.at_level(logging.WARNING, logger="handflow.node.human"):
        for i in range(500):
            ledger.note("raw", f"bad payload {i}")
    assert len(caplog.records) == 1 and "bad payload 0" in caplog.text and "handflow/g/glove/frames" in caplog.text
    assert ledger.counts() == {"raw": 500, "aux": 0}
    (event,) = ledger.report()
    assert (event.kind, event.node, event.topic, event.count, event.detail) == (
        "dropped",
        "human",
        "handflow/g/glove/frames",
        500,
        "bad payload 499",
    )
    event.check()
    assert ledger.report() == []  # reported once
    ledger.note("raw", "again")
    assert [e.count for e in ledger.report()] == [1] and ledger.counts()["raw"] == 501


def test_the_next_log_line_says_how_many_were_not_logged(caplog, monkeypatch):
    clock = [100.0]
    monkeypatch.setattr("handflow.framework.runtime.drops.time.monotonic", lambda: clock[0])
    ledger = DropLedger("n", {"in": "handflow/g/a/b"}, logging.getLogger("handflow.node.n"), log_interval_s=5)
    with caplog.at_level(logging.WARNING, logger="handflow.node.n"):
        for reason in ("first", "second", "third"):
            ledger.note("in", reason)
        clock[0] += 5
        ledger.note("in", "fourth")
    assert [r.getMessage().rsplit(": ", 1)[1] for r in caplog.records] == ["first", "fourth"]
    assert "2 more since the last report" in caplog.records[1].getMessage()
