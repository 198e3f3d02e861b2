"""Protocol module: record codec, timestamp escaping, incremental framing with resync (no I/O)."""

import numpy as np
import pytest

from handflow.plugins.glove import protocol as P

FMT = P.RecordFormat(22, timestamp=True, status=True)


def _record(i: int) -> bytes:
    values = (np.arange(22) + i) % 255 + 1
    return P.encode_record(values, FMT, device_time=1000 * i, status=0x81)


def test_record_round_trip_and_length():
    rec = _record(7)
    assert len(rec) == 30 and rec[0] == ord("S") and rec[-1] == 0 and rec.count(0) == 1
    (parsed,) = P.StreamParser(FMT).feed(rec)
    assert parsed.values.tolist() == ((np.arange(22) + 7) % 255 + 1).tolist()
    assert parsed.device_time == 7000 and parsed.status == 0x81


@pytest.mark.parametrize("ticks", [0, 1, 0x100, 0x10000, 0x01000000, 0xFFFFFFFF, 0x00FF00FF])
def test_timestamp_zero_bytes_are_escaped(ticks):
    five = P.encode_timestamp(ticks)
    assert 0 not in five and five[0] & 0x80
    assert P.decode_timestamp(five) == ticks


def test_values_are_clamped_to_wire_range():
    rec = P.encode_record(np.r_[0, 300, np.full(20, 5)], P.RecordFormat())
    assert rec[1] == 1 and rec[2] == 255 and len(rec) == 24


def test_parser_handles_arbitrary_chunking():
    stream = b"".join(_record(i) for i in range(50))
    rng = np.random.default_rng(1)
    cuts = np.sort(rng.choice(len(stream), 40, replace=False))
    parser = P.StreamParser(FMT)
    out = []
    for chunk in np.split(np.frombuffer(stream, np.uint8), cuts):
        out += parser.feed(chunk.tobytes())
    assert [r.device_time for r in out] == [1000 * i for i in range(50)]
    assert parser.counters.corrupt == 0


def test_garbage_before_a_record_is_skipped_and_the_record_kept():
    parser = P.StreamParser(FMT)
    out = parser.feed(_record(1) + b"SG\x13\x11junk" + _record(2) + b"\x00\x00xyz\x00" + _record(3))
    assert [r.device_time for r in out] == [1000, 2000, 3000]
    assert parser.counters.salvaged == 1 and parser.counters.corrupt == 2


def test_lost_nul_loses_only_the_damaged_record():
    parser = P.StreamParser(FMT)
    out = parser.feed(_record(1)[:-1] + _record(2) + _record(3))
    assert [r.device_time for r in out] == [2000, 3000]
    assert parser.counters.corrupt == 1


@pytest.mark.parametrize("damage", ["zero", "drop", "truncate", "status_bit7"])
def test_damaged_record_is_counted_and_sync_kept(damage):
    bad = bytearray(_record(2))
    if damage == "zero":
        bad[5] = 0
    elif damage == "drop":
        del bad[10:12]
    elif damage == "truncate":
        bad = bad[:12] + b"\x00"
    else:
        bad[-2] &= 0x7F
    parser = P.StreamParser(FMT)
    out = parser.feed(_record(1) + bytes(bad) + _record(3))
    assert [r.device_time for r in out] == [1000, 3000]
    assert parser.counters.corrupt >= 1


def test_error_pairs_are_decoded():
    rec = P.encode_record(np.full(22, 9), FMT, 5, errors=("sample_rate", "glove_unplugged"))
    (parsed,) = P.StreamParser(FMT).feed(rec)
    assert parsed.errors == ("sample_rate", "glove_unplugged")


def test_buffer_without_nul_is_bounded():
    parser = P.StreamParser(FMT, max_buffer=100)
    assert parser.feed(b"\x55" * 500) == []
    assert parser.counters.garbage_bytes == 500
    assert [r.device_time for r in parser.feed(b"\x00" + _record(4))] == [4000]


def test_commands_and_replies():
    assert P.set_period(1152, 1) == b"T\x04\x80\x00\x01"
    assert P.set_mask(0x7FFF7F) == b"M\x7f\xff\x7f"
    assert P.query("G") == b"?G" and P.set_flag("U", True) == b"U\x01"
    assert P.period_words(100) == (1152, 1) and P.period_words(0.5) == (57600, 4)
    assert P.parse_query_reply("G", b"junk?G\x03\x00rest") == (b"\x03", 8)
    assert P.parse_query_reply("K", b"?K\x7f\xff") is None  # incomplete
    assert P.parse_query_reply("F", b"?F\x00\x00") == (b"\x00", 4)  # payload may be 0
    assert P.parse_ack("T", b"xxT\x00") == 4
    with pytest.raises(ValueError, match="no binary query"):
        P.query("Z")
