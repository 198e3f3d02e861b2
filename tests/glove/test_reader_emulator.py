"""Reader against the byte-exact emulator over a real pty, with every injected fault."""

import time

import numpy as np
import pytest
import serial

from handflow.plugins.glove import protocol as P
from handflow.plugins.glove.emulator import Fault, GloveEmulator, array_source
from handflow.plugins.glove.node import EmulatorParams, build_emulator
from handflow.plugins.glove.reader import GloveReader, ReaderConfig

RATE = 200.0
PERIOD_TICKS = P.period_words(RATE)[0]


def _frames(n=64):
    return (np.arange(n)[:, None] * 3 + np.arange(22)[None, :]) % 250 + 2


def _run(faults, enough, stall_timeout_s=0.3, timeout_s=30.0, **emulator_kw):
    """Stream until ``enough(emulator, records)`` holds (a busy machine takes longer; at most ``timeout_s``);
    returns (emulator, reader, received records)."""
    with GloveEmulator(array_source(_frames()), faults=faults, seed=3, **emulator_kw) as emu:
        reader = GloveReader(ReaderConfig(port=emu.path, glove_rate_hz=RATE, stall_timeout_s=stall_timeout_s)).start()
        records = []
        deadline = time.monotonic() + timeout_s
        while not enough(emu, records) and time.monotonic() < deadline:
            time.sleep(0.02)
            records += [rec for rec, _ in reader.drain()]
        reader.stop()
    return emu, reader, records + [rec for rec, _ in reader.drain()]


def _at_least(n):
    return lambda emu, records: len(records) >= n


def _recovered(emu, records) -> bool:
    """The fault happened and 20 records came after it."""
    return bool(emu.fault_log) and sum(r.device_time > emu.fault_log[0]["ticks"] for r in records) >= 20


def _in_flight_at_disconnect(emu, ticks) -> set:
    """Records the emulator wrote after the last one the reader got before a disconnect: still in
    the pty when it closed, they go with it, as a real link's unread bytes do when it drops (a
    reader starved by other work may not have read them yet).  Only such a tail may go missing."""
    cuts = [f["ticks"] for f in emu.fault_log if f["kind"] == "disconnect"]
    gone = set()
    for cut in cuts:
        got = max((t for t in ticks if t < cut), default=-1)
        gone |= {t for _, t in emu.sent if got < t < cut}
    return gone


def _check_integrity(emu, records):
    """In order, no duplicates, nothing invented, no good record lost (except the stream's tail)."""
    ticks = [r.device_time for r in records]
    sent = [t for _, t in emu.sent]
    assert ticks == sorted(ticks) and len(set(ticks)) == len(ticks)
    assert set(ticks) <= set(sent)
    last = max(ticks)
    lost = {t for t in sent if t < last} - set(ticks) - emu.damaged - _in_flight_at_disconnect(emu, ticks)
    assert not lost, f"good records lost: {sorted(lost)}"
    values = {t: r.values for t, r in zip(ticks, records)}
    frames = _frames()
    for k, t in emu.sent:
        if t in values:
            assert values[t].tolist() == frames[k % len(frames)].tolist()


def test_emulator_answers_byte_for_byte():
    with GloveEmulator(period=(1152, 1)) as emu, serial.Serial(emu.path, 115200, timeout=0.5) as port:

        def ask(cmd: bytes, n: int) -> bytes:
            port.write(cmd)
            return port.read(n)

        assert ask(b"?G", 4) == b"?G\x03\x00"
        assert ask(b"?S", 4) == b"?S\x16\x00"
        assert ask(b"?K", 6) == b"?K\x7f\xff\x7f\x00"
        assert ask(b"?T", 7) == b"?T\x04\x80\x00\x01\x00"
        assert ask(b"U\x01", 2) == b"U\x00"
        assert ask(b"?U", 4) == b"?U\x01\x00"
        assert ask(b"Z", 3) == b"e?\x00"
        rec = ask(b"G", 25)
        assert len(rec) == 25 and rec[0] == ord("G") and rec[-2] & 0x80 and rec[-1] == 0
        port.write(b"S")
        first = port.read(25 * 3)
        port.write(b"?G")  # ignored while streaming
        port.write(b"\x03")
        time.sleep(0.1)
        port.reset_input_buffer()
        assert ask(b"?G", 4) == b"?G\x03\x00"
    assert first.count(b"\x00") == 3 and first.startswith(b"S")


def test_clean_stream_arrives_complete_in_order_at_the_configured_rate():
    emu, reader, records = _run([], _at_least(0.6 * RATE))
    _check_integrity(emu, records)
    assert len(records) >= 0.6 * RATE
    deltas = np.diff([r.device_time for r in records])
    assert np.all(np.abs(deltas - PERIOD_TICKS) <= 1)  # device clock: exactly one period apart
    state, counters = reader.snapshot()
    assert counters["corrupt"] == 0 and counters["gaps"] == 0 and counters["reconnects"] == 0


def test_bursty_jittery_rfcomm_like_link_loses_nothing():
    emu, reader, records = _run([Fault("garbage", 30, 10)], _at_least(0.6 * RATE), burst=5, jitter_s=0.03)
    _check_integrity(emu, records)
    assert len(records) >= 0.6 * RATE
    _, counters = reader.snapshot()
    assert counters["reconnects"] == 0 and counters["gaps"] == 0


@pytest.mark.parametrize(
    "fault",
    [
        Fault("garbage", 40, 24),
        Fault("drop_bytes", 40, 3),
        Fault("truncate", 40),
        Fault("zero_value", 40),
        Fault("disconnect", 40, duration_s=0.3),
        Fault("stall", 40, duration_s=0.6),
    ],
    ids=lambda f: f.kind,
)
def test_reader_recovers_from_fault(fault):
    emu, reader, records = _run([fault], _recovered)
    assert emu.fault_log and emu.fault_log[0]["kind"] == fault.kind
    _check_integrity(emu, records)
    fault_ticks = emu.fault_log[0]["ticks"]
    after = [r for r in records if r.device_time > fault_ticks]
    assert len(after) >= 20, "reader did not recover after the fault"
    _, counters = reader.snapshot()
    if fault.kind in ("garbage", "drop_bytes", "truncate", "zero_value"):
        assert counters["corrupt"] >= 1
        # corrupt bytes never cost the link; only silence does (a starved machine can stall the emulator)
        assert counters["reconnects"] == counters["stalls"]
    else:
        assert counters["reconnects"] >= 1
    if fault.kind == "stall":
        assert counters["stalls"] == 1 and counters["gaps"] >= 1


def test_unresponsive_port_is_reported_and_retried(tmp_path):
    reader = GloveReader(
        ReaderConfig(port=str(tmp_path / "nothing"), backoff_initial_s=0.01, backoff_max_s=0.02)
    ).start()
    time.sleep(0.2)
    reader.stop()
    _, counters = reader.snapshot()
    assert counters["io_errors"] >= 2 and counters["reconnects"] >= 1
    assert "nothing" in reader.last_error


def test_a_running_emulator_keeps_a_bounded_record_log():
    """The node's and glove-emulator's emulator stream for hours: their record log must not grow with them."""
    with build_emulator(EmulatorParams(), log_limit=20) as emu:
        reader = GloveReader(ReaderConfig(port=emu.path, glove_rate_hz=RATE)).start()
        got = []
        deadline = time.monotonic() + 10
        while emu.counters["records"] < 100 and time.monotonic() < deadline:
            time.sleep(0.02)
            got += reader.drain()
        reader.stop()
    assert emu.counters["records"] >= 100 and got
    assert len(emu.sent) == 20
