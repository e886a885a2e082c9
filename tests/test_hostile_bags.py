"""Hostile ROS bags and MCAP files (issue "Hostile input, round 3"): chunks that inflate to
gigabytes, sizes and lengths that lie, fields a record lacks. Each test is named for the defect
it pins, and failed before its fix: each command runs in a subprocess under an address-space
limit (``LIMIT``) and a time limit (``TIMEOUT``), as ``make fuzz`` runs its cases, so a reader
that inflates without a bound is a failure, not a machine that swaps.

The bombs are made cheaply: bz2 streams and zstd frames one after another read as one (as
rosbags' own decompressors read them), and an lz4 frame of independent blocks is one block
repeated; none is ever inflated here."""

from __future__ import annotations

import bz2
import struct
import sys
import time
from pathlib import Path

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import pytest

from tests import ros_writer
from tests.conftest import limited
from tests.ros_writer import Messages

if sys.version_info >= (3, 14):
    from compression import zstd
else:
    from backports import zstd

pytestmark = pytest.mark.slow

#: Seconds a command may run (under conftest.LIMIT of address space, as make fuzz's).
TIMEOUT = 60
GIB4 = 4 << 30
G = 9.80665


def tumblecal(*args: str | Path) -> tuple[int, str, str, float]:
    """``tumblecal ARGS`` in a subprocess under conftest.LIMIT and TIMEOUT: exit status, stdout,
    stderr, and the seconds it took."""
    start = time.monotonic()
    done = limited(*args, timeout=TIMEOUT)
    return done.code, done.out, done.err, time.monotonic() - start


def assert_error(result: tuple[int, str, str, float], expected: str) -> None:
    """Exit 2, one error line and it ``expected`` (a hint beside it), no internal error."""
    code, _out, err, _ = result
    assert code == 2, err
    assert "Traceback" not in err
    assert "internal error" not in err
    lines = err.splitlines()
    assert [ln for ln in lines if ln.startswith("error:")] == [f"error: {expected}"], err
    assert all(ln.startswith(("error:", "hint:")) for ln in lines), err


# -- bombs ----------------------------------------------------------------------------------

#: 64 MiB of zeros, compressed.
_ZEROS = bytes(64 << 20)


def bz2_bomb(size: int = GIB4) -> bytes:
    """bz2 streams one after another that inflate to ``size`` bytes of zeros (447 bytes a 64 MiB)."""
    return bz2.compress(_ZEROS, 1) * (size // len(_ZEROS))


def zstd_bomb(size: int = GIB4) -> bytes:
    """zstd frames one after another that inflate to ``size`` bytes of zeros."""
    return zstd.compress(_ZEROS, 1) * (size // len(_ZEROS))


def lz4_bomb(size: int = GIB4) -> bytes:
    """One lz4 frame of independent 4 MiB blocks, no checksum, that inflates to ``size`` bytes
    of zeros: a frame's header (7 bytes), its one block repeated, the end mark."""
    block = 4 << 20
    frame: bytes = lz4.frame.compress(
        bytes(block),
        block_size=lz4.frame.BLOCKSIZE_MAX4MB,
        block_linked=False,
        content_checksum=False,
        store_size=False,
    )
    head, body = frame[:7], frame[7:-4]
    assert frame[-4:] == bytes(4)
    assert struct.unpack_from("<I", body)[0] + 4 == len(body)
    return head + body * (size // block) + bytes(4)


# -- ROS 1 bags -----------------------------------------------------------------------------


def still(rows: int = 20) -> Messages:
    rng = np.random.default_rng(3)
    t = 1_700_000_000_000_000_000 + np.arange(rows, dtype=np.int64) * 5_000_000
    return Messages(t, np.array([0.1, -0.2, G]) + rng.normal(0, 0.01, (rows, 3)), rng.normal(0, 0.001, (rows, 3)))


def ros1_bag(tmp_path: Path, rows: int = 20) -> bytes:
    """A ROS 1 bag of lz4 chunks (16 KiB each), an Imu topic of ``rows`` messages."""
    return ros_writer.write(tmp_path / "good.bag", "ros1", {"/imu/data_raw": still(rows)}, compressed=True).read_bytes()


def _header(fields: list[tuple[str, bytes]]) -> bytes:
    parts = [struct.pack("<I", len(n) + 1 + len(v)) + n.encode() + b"=" + v for n, v in fields]
    return struct.pack("<I", sum(map(len, parts))) + b"".join(parts)


def ros1_records(bag: bytes) -> list[tuple[int, list[tuple[str, bytes]], bytes]]:
    """Each top-level record of a ROS 1 bag: (its byte, its header's fields in order, its data)."""
    at, out = bag.index(b"\n") + 1, []
    while at < len(bag):
        (head,) = struct.unpack_from("<I", bag, at)
        fields, k = [], at + 4
        while k < at + 4 + head:
            (size,) = struct.unpack_from("<I", bag, k)
            name, _, value = bag[k + 4 : k + 4 + size].partition(b"=")
            fields.append((name.decode(), value))
            k += 4 + size
        (size,) = struct.unpack_from("<I", bag, at + 4 + head)
        out.append((at, fields, bag[at + 8 + head : at + 8 + head + size]))
        at += 8 + head + size
    return out


def with_chunk(bag: bytes, which: int, data: bytes, **change: bytes) -> tuple[bytes, int]:
    """``bag`` with its chunk ``which`` (-1: the last) holding ``data`` and its header's fields
    ``change``d (compression, size), the bag header's index_pos moved by as many bytes as the
    chunk grew (the chunks before it, and it, stay where they were); and the chunk's byte."""
    records = ros1_records(bag)
    at, fields, old = [r for r in records if dict(r[1])["op"] == b"\x05"][which]
    fields = [(n, change.get(n, v)) for n, v in fields]
    record = _header(fields) + struct.pack("<I", len(data)) + data
    end = at + 8 + len(_header(fields)) - 4 + len(old)
    out = bytearray(bag[:at] + record + bag[end:])
    top, _head, _ = records[0]
    where = bag.index(b"index_pos=", top) + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", bag, where)
    if index_pos:
        struct.pack_into("<Q", out, where, index_pos + len(record) - (end - at))
    return bytes(out), at


def unindexed(bag: bytes) -> bytes:
    """``bag`` as a recording cut short leaves it: its header's index_pos 0 (rosbag writes it last)."""
    where = bag.index(b"index_pos=") + len(b"index_pos=")
    return bag[:where] + bytes(8) + bag[where + 8 :]


@pytest.mark.parametrize("command", ["logs", "noise", "segment", "solve"])
def test_a_ros1_bz2_chunk_that_inflates_to_4_gib_is_refused_by_its_size(tmp_path: Path, command: str) -> None:
    """Before: rosbags inflated the chunk whole (bz2.decompress): 47 s and 8.1 GiB resident for
    `noise`, then 'Could not read uint8 field 'op''; under the limit, 'Unable to allocate output
    buffer' after 13-23 s. Now its 'size' (4 GiB less a byte) is refused before a byte is
    inflated: 0.8 s, 85 MiB."""
    bag, at = with_chunk(ros1_bag(tmp_path), 0, bz2_bomb(), compression=b"bz2", size=struct.pack("<I", GIB4 - 1))
    path = tmp_path / "bomb.bag"
    path.write_bytes(bag)
    commands: dict[str, list[str | Path]] = {
        "logs": ["logs", path],
        "noise": ["noise", path],
        "segment": ["segment", path],
        "solve": ["solve", "--log", path, "-o", tmp_path / "cal.json"],
    }
    result = tumblecal(*commands[command])
    assert_error(
        result,
        f"{path}: cannot read this ROS 1 bag: the chunk at byte {at}: its 'size' is 4,294,967,295 bytes: "
        "more than a chunk holds (at most 1G)",
    )
    assert result[3] < 20
    assert not (tmp_path / "cal.json").exists()


def test_a_ros1_lz4_chunk_whose_size_lies_stops_at_its_size(tmp_path: Path) -> None:
    """Before: rosbags inflated what the data gave whatever the chunk's 'size' said
    (lz4.frame.decompress): 2.1 GiB resident, then 'Failed to resize buffer'. Now inflated up to
    its 'size' and a byte: exit 2 naming the chunk and the field (1.7 s, 120 MiB)."""
    good = ros1_bag(tmp_path)
    bag, at = with_chunk(good, 0, lz4_bomb())
    size = struct.unpack("<I", dict(ros1_records(good)[1][1])["size"])[0]
    path = tmp_path / "bomb.bag"
    path.write_bytes(bag)
    result = tumblecal("logs", path)
    assert_error(
        result,
        f"{path}: cannot read this ROS 1 bag: the chunk at byte {at}: it inflates to more than its 'size' "
        f"({size:,} bytes)",
    )
    assert result[3] < 20


def test_a_bomb_in_a_ros1_bag_without_its_index_ends_the_walk_with_a_note(tmp_path: Path) -> None:
    """The walk of a bag without its index (Unindexed) inflated each chunk whole (bz2.decompress):
    a bomb in its second chunk took 28 s to run out of the address space. Now, as for any damaged
    chunk, the walk stops there with a note, and the messages before it are read."""
    good = ros1_bag(tmp_path, rows=120)
    chunks = [r for r in ros1_records(good) if dict(r[1])["op"] == b"\x05"]
    assert len(chunks) > 2
    bag, at = with_chunk(good, 1, bz2_bomb(), compression=b"bz2")
    size = struct.unpack("<I", dict(chunks[1][1])["size"])[0]
    path = tmp_path / "cut.bag"
    path.write_bytes(unindexed(bag))
    code, _out, err, took = tumblecal("noise", path)
    assert code == 0, err
    assert took < 20
    assert (
        f"note: {path}: the ROS 1 bag has no index (a recording cut short?): its records read one after another, "
        f"up to the chunk at byte {at}, which cannot be read (it inflates to more than its 'size' ({size:,} bytes))"
    ) in " ".join(err.split())
    assert f"read /imu/data_raw (accelerometer, {len_before(good, 1)} samples" in err


def len_before(bag: bytes, which: int) -> int:
    """The messages of the chunks of ``bag`` before its chunk ``which`` (their index records)."""
    records = ros1_records(bag)
    starts = [k for k, r in enumerate(records) if dict(r[1])["op"] == b"\x05"]
    index = [r for r in records[: starts[which]] if dict(r[1])["op"] == b"\x04"]
    return sum(struct.unpack("<I", dict(r[1])["count"])[0] for r in index)


@pytest.mark.parametrize("field", ["conn", "time", "op"])
def test_a_ros1_message_without_a_field_ends_the_walk_with_a_note(tmp_path: Path, field: str) -> None:
    """Before: 'internal error: KeyError' (a bag without its index, its first chunk's 30th
    message without its 'conn' or 'time'; without 'op', it was taken for no message at all and
    the walk went on). Now the walk stops at that record with a note naming it and the field: the
    29 messages before it are read."""
    good = ros1_bag(tmp_path, rows=120)
    records = ros1_records(good)
    at, _fields, data = next(r for r in records if dict(r[1])["op"] == b"\x05")
    inner = lz4.frame.decompress(data)
    k, seen = 0, 0
    while True:  # the chunk's 30th message
        (head,) = struct.unpack_from("<I", inner, k)
        if b"op=\x02" in inner[k : k + 4 + head]:
            seen += 1
            if seen == 30:
                break
        k += 8 + head + struct.unpack_from("<I", inner, k + 4 + head)[0]
    name = field.encode() + b"="
    place = inner.index(name, k)
    broken = inner[:place] + b"X" * len(field) + inner[place + len(field) :]  # the field renamed
    bag, at = with_chunk(good, 0, lz4.frame.compress(broken))
    path = tmp_path / "cut.bag"
    path.write_bytes(unindexed(bag))
    code, _out, err, _ = tumblecal("noise", path)
    assert code == 0, err
    assert "read /imu/data_raw (accelerometer, 29 samples" in err
    assert (
        f"up to the chunk at byte {at}, which cannot be read (its record at byte {k}: its header has no "
        f"'{field}' field), as rosbag reindex would"
    ) in " ".join(err.split())


# -- MCAP -----------------------------------------------------------------------------------


def mcap_records(data: bytes) -> list[tuple[int, int, bytes]]:
    """Each top-level record of an MCAP file up to its footer: (its byte, opcode, content)."""
    at, out = 8, []
    while at + 9 <= len(data):
        op, size = data[at], struct.unpack_from("<Q", data, at + 1)[0]
        out.append((at, op, data[at + 9 : at + 9 + size]))
        if op == 2:
            break
        at += 9 + size
    return out


def _record(op: int, body: bytes) -> bytes:
    return bytes([op]) + struct.pack("<Q", len(body)) + body


def unfinished_mcap(tmp_path: Path, rows: int = 400) -> bytes:
    """An MCAP file of zstd chunks cut short after its last chunk (no summary, no footer), as a
    recording stopped leaves it: its records up to its data end."""
    path = ros_writer.write(tmp_path / "good.mcap", "plain", {"/imu/data_raw": still(rows)}, compressed=True)
    data = path.read_bytes()
    end = next(at for at, op, _ in mcap_records(data) if op == 15)
    return data[:end]


def chunk_of(body: bytes, records: bytes, size: int) -> bytes:
    """An MCAP chunk's content as ``body``'s (its times), holding ``records`` (zstd) and saying
    they inflate to ``size``, with no crc."""
    return body[:16] + struct.pack("<QI", size, 0) + struct.pack("<I", 4) + b"zstd" + struct.pack("<Q", len(records))


def test_an_mcap_zstd_chunk_whose_size_lies_ends_the_walk_with_a_note(tmp_path: Path) -> None:
    """Before: the walk of an MCAP file without its summary (Unfinished) inflated each chunk
    whole (zstd.decompress): 4 GiB in a 350 KB file, still reading after 300 s at 8.1 GiB
    resident. Now inflated up to its uncompressed_size and a byte: the walk stops there with a
    note (0.6 s, 88 MiB)."""
    data = unfinished_mcap(tmp_path, rows=4000)
    chunks = [(at, body) for at, op, body in mcap_records(data) if op == 6]
    assert len(chunks) == 2
    at, body = chunks[-1]
    (size,) = struct.unpack_from("<Q", body, 16)
    bomb = zstd_bomb()
    record = _record(6, chunk_of(body, bomb, size) + bomb)
    path = tmp_path / "bomb.mcap"
    path.write_bytes(data[:at] + record)
    code, _out, err, took = tumblecal("noise", path)
    assert (code, took < 20) == (0, True), err
    assert (
        f"up to the chunk at byte {at}, which cannot be read (it inflates to more than its 'uncompressed_size' "
        f"({size:,} bytes)), as mcap recover would"
    ) in " ".join(err.split())


def test_an_mcap_zstd_chunk_of_4_gib_in_the_first_chunk_is_exit_2(tmp_path: Path) -> None:
    """Before: 'cannot be read (Unable to allocate output buffer.)' once the address space ran
    out. Its uncompressed_size says what it inflates to (4 GiB): refused before it is inflated,
    and no message before it: exit 2 naming the chunk and the field."""
    data = unfinished_mcap(tmp_path, rows=20)
    at, body = next((at, body) for at, op, body in mcap_records(data) if op == 6)
    bomb = zstd_bomb()
    path = tmp_path / "bomb.mcap"
    path.write_bytes(data[:at] + _record(6, chunk_of(body, bomb, GIB4) + bomb))
    result = tumblecal("logs", path)
    assert_error(
        result,
        f"{path}: the MCAP file has no summary, and no channel record up to the chunk at byte {at}, which cannot "
        "be read (its 'uncompressed_size' is 4,294,967,296 bytes: more than a chunk holds (at most 1G)): nothing "
        "to read",
    )
    assert result[3] < 20


@pytest.mark.parametrize("field", ["topic", "message_encoding"])
def test_an_mcap_channel_whose_string_length_lies_is_one_line(tmp_path: Path, field: str) -> None:
    """Before: 'internal error: struct.error: unpack_from requires a buffer of at least
    4294967307 bytes' (a channel's topic length 4 GiB, in an MCAP file without its summary).
    Now the walk stops at that record, naming it and the field: exit 2, as it is the only
    channel."""
    data = unfinished_mcap(tmp_path)
    at, body = next((at, body) for at, op, body in mcap_records(data) if op == 6)
    start = 28 + 4 + 4 + 8
    inner = zstd.decompress(body[start:])
    k = 0
    while inner[k] != 4:  # the chunk's channel record
        k += 9 + struct.unpack_from("<Q", inner, k + 1)[0]
    (length,) = struct.unpack_from("<Q", inner, k + 1)
    (topic,) = struct.unpack_from("<I", inner, k + 9 + 4)
    where = 4 if field == "topic" else 4 + 4 + topic
    lied = inner[: k + 9 + where] + struct.pack("<I", 2**32 - 1) + inner[k + 9 + where + 4 :]
    records = zstd.compress(lied)
    path = tmp_path / "lies.mcap"
    path.write_bytes(data[:at] + _record(6, chunk_of(body, records, len(lied)) + records))
    result = tumblecal("logs", path)
    assert_error(
        result,
        f"{path}: the MCAP file has no summary, and no channel record up to the chunk at byte {at}, which cannot "
        f"be read (its record at byte {k}: its '{field}' is 4,294,967,295 bytes long: past its end "
        f"({length - where - 4:,} bytes on)): nothing to read",
    )


def test_max_spool_bounds_what_a_bag_s_chunks_inflate_in_all(tmp_path: Path) -> None:
    """--max-spool bounded only the copy of a log from a pipe: a bag's chunks inflated without
    a bound in all. Now a pass over the bag inflates at most --max-spool (4G when not given):
    past it, exit 2 naming the chunk that would pass it, before it is inflated."""
    path = ros_writer.write(tmp_path / "long.bag", "ros1", {"/imu/data_raw": still(4000)}, compressed=True)
    chunks = [(at, dict(f)) for at, f, _ in ros1_records(path.read_bytes()) if dict(f)["op"] == b"\x05"]
    sizes = np.cumsum([struct.unpack("<I", f["size"])[0] for _, f in chunks])
    at = chunks[int(np.searchsorted(sizes, 1 << 20, side="right"))][0]
    result = tumblecal("segment", path, "--max-spool", "1M")
    assert_error(
        result,
        f"{path}: its chunks inflate to more than --max-spool 1M in all: the chunk at byte {at} would pass it",
    )
    _code, _, err, _ = tumblecal("segment", path, "--max-spool", "2M")
    assert "inflate" not in err
