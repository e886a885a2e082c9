"""The binary logs of ``make fuzz`` (tests/fuzz.py): a small good log of each format, written by
the tests' own writers, and mutators that know each format's framing, so that a mutation lands
on what a reader must not trust: a declared count, a length, an offset, a definition given twice,
a compression claimed, a chunk that inflates to gigabytes. Each mutator takes the good bytes and a
seeded random generator and returns the mutated bytes.

- PX4 ULog (``.ulg``): 3-byte message headers (size, type); formats (``F``: array counts, field
  types), subscriptions (``A``), the flag bits' appended-data offsets (``B``).
- ArduPilot DataFlash, binary (``.bin``): FMT messages (type 128: its type, length, name, format
  string), a message's length byte; and text (``.log``): an FMT line's fields.
- ROS 1 bag (``.bag``): records (header length, fields, data length), a chunk's ``compression``
  and ``size``, the header's ``index_pos``; chunks lz4 or bz2.
- MCAP (``.mcap``): records (opcode, 8-byte length), a schema's and a channel's string lengths, a
  chunk's compression and sizes, zstd chunks.
- Compressed CSV (``.csv.gz`` ``.bz2`` ``.xz`` ``.zst``): the stream's header bytes, a bomb.
"""

from __future__ import annotations

import bz2
import gzip
import io
import lzma
import random
import struct
from pathlib import Path

import numpy as np

#: Numbers a declared count, length or offset is replaced by.
HUGE = [0, 1, 2**15, 2**16 - 1, 2**31 - 1, 2**32 - 1, 2**40, 2**63 - 1, 2**64 - 1]
#: Text a count written in a format is replaced by.
COUNTS = ["1099511627776", "²", "٣", "-1", "0", "9" * 5000, "", "1e3", "0x10", " 3", "65536"]


def _number(rng: random.Random, size: int) -> int:
    return rng.choice([n for n in HUGE if n < 2 ** (8 * size)] + [rng.randrange(2 ** (8 * size))])


def _put(data: bytes, at: int, fmt: str, value: int) -> bytes:
    width = struct.calcsize(fmt)
    return data[:at] + struct.pack(fmt, value % 2 ** (8 * width)) + data[at + width :]


# -- PX4 ULog ---------------------------------------------------------------------------------


def ulog_seed() -> bytes:
    from tests import ulog_writer

    t, xyz = _faces(400)
    parts = [ulog_writer.header(int(t[0]) - 1000), ulog_writer.definitions(("sensor_accel", "sensor_gyro"))]
    parts += [
        ulog_writer.message("B", bytes(8) + bytes(8) + bytes(24)),  # flag bits: no appended data
        ulog_writer.subscribe(10, "sensor_accel"),
        ulog_writer.subscribe(11, "sensor_gyro"),
    ]
    accel = ulog_writer.samples(10, "sensor_accel", t, xyz, np.full(len(t), 25.0))
    gyro = ulog_writer.samples(11, "sensor_gyro", t + 3, 0.01 * xyz, np.full(len(t), 25.0))
    body = [m for pair in zip(accel, gyro, strict=True) for m in pair]
    for k in range(0, len(body), 100):
        body.insert(k, ulog_writer.message("S", ulog_writer.SYNC))
    head = parts[0]
    flags = parts[2]
    return head + flags + parts[1] + b"".join(parts[3:]) + b"".join(body)


def _ulog_messages(data: bytes) -> list[tuple[int, int, int]]:
    """Each message's (first byte, size, type) from byte 16."""
    out, at = [], 16
    while at + 3 <= len(data):
        size, kind = struct.unpack_from("<HB", data, at)
        out.append((at, size, kind))
        at += 3 + size
    return out


def ulog_mutate(data: bytes, rng: random.Random) -> bytes:
    messages = _ulog_messages(data)
    of = {k: [m for m in messages if m[2] == ord(k)] for k in "FABD"}
    kind = rng.randrange(7)
    if kind == 0 and of["F"]:  # an array count rewritten
        at, size, _ = rng.choice(of["F"])
        text = data[at + 3 : at + 3 + size].decode()
        fields = text.split(";")
        k = rng.randrange(len(fields) - 1) if len(fields) > 1 else 0
        kind_name = fields[k].split(" ")[0]
        base = kind_name.partition("[")[0].split(":")[-1]
        fields[k] = fields[k].replace(kind_name.split(":")[-1], f"{base}[{rng.choice(COUNTS)}]", 1)
        body = ";".join(fields).encode()
        return data[:at] + struct.pack("<HB", len(body) % 65536, ord("F")) + body + data[at + 3 + size :]
    if kind == 1 and of["F"]:  # a format given twice, the second contradicting the first
        at, size, _ = rng.choice(of["F"])
        text = data[at + 3 : at + 3 + size].decode()
        name = text.partition(":")[0]
        other = rng.choice([f"{name}:float x;", f"{name}:uint64_t timestamp;", f"{name}:{name} nested;", f"{name}:"])
        body = other.encode()
        extra = struct.pack("<HB", len(body), ord("F")) + body
        return data[: at + 3 + size] + extra + data[at + 3 + size :]
    if kind == 2 and messages:  # a message's size lies
        at, size, _ = rng.choice(messages)
        return _put(data, at, "<H", rng.choice([0, 1, size - 1, size + 1, 65535, rng.randrange(65536)]))
    if kind == 3 and of["B"]:  # the flag bits: appended-data offsets, incompatible flags
        at, _, _ = of["B"][0]
        where = at + 3 + rng.choice([8, 16, 24, 32])
        width = "<B" if where < at + 3 + 16 else "<Q"
        value = rng.choice([1, 3, 128, 255]) if width == "<B" else rng.choice([*HUGE, len(data) // 2, len(data) + 9])
        return _put(data, where, width, value)
    if kind == 4 and of["A"]:  # a subscription's msg_id or instance
        at, _, _ = rng.choice(of["A"])
        return _put(data, at + 3 + rng.choice([0, 1]), "<B", rng.randrange(256))
    if kind == 5 and of["D"]:  # a sample's msg_id
        at, _, _ = rng.choice(of["D"])
        return _put(data, at + 3, "<H", rng.choice([10, 11, 12, 0, 65535]))
    if kind == 6:  # a combined topic without its relative timestamp
        body = b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;float[3] accelerometer_m_s2;"
        sub = struct.pack("<BH", 0, 12) + b"sensor_combined"
        sample = struct.pack("<HQ6f", 12, 5_000_000, *[0.0] * 5, 9.8)
        add = b"".join(struct.pack("<HB", len(p), ord(k)) + p for k, p in (("F", body), ("A", sub), ("D", sample)))
        first = of["A"][0][0] if of["A"] else len(data)
        return data[:first] + add + data[first:]
    return data[: rng.randrange(len(data))]


# -- ArduPilot DataFlash ----------------------------------------------------------------------


def dataflash_seed(folder: Path) -> tuple[bytes, bytes]:
    """The binary log and its text form."""
    from tests import dataflash_writer

    t, xyz = _faces(300)
    path = dataflash_writer.write(folder / "seed.bin", t, 9.80665 * xyz)
    text = dataflash_writer.text_of(path, folder / "seed.log")
    return path.read_bytes(), text.read_bytes()


def dataflash_mutate(data: bytes, rng: random.Random) -> bytes:
    fmts = [i for i in range(len(data) - 3) if data[i : i + 3] == b"\xa3\x95\x80"]
    kind = rng.randrange(5)
    if fmts and kind == 0:  # an FMT's length byte: 0, 1, 3, 255, or another message's
        at = rng.choice(fmts)
        return _put(data, at + 4, "<B", rng.choice([0, 1, 2, 3, 4, 89, 200, 255, rng.randrange(256)]))
    if fmts and kind == 1:  # an FMT's format string: unknown letters, arrays, longer than its length
        at = rng.choice(fmts)
        letters = rng.choice(["a" * 16, "Z" * 16, "QQQQQQQQQQQQQQQQ", "X", "", "N" * 16, "Q\x00f", "é"])
        raw = letters.encode()[:16].ljust(16, b"\0")
        return data[: at + 9] + raw + data[at + 25 :]
    if fmts and kind == 2:  # an FMT given twice: the same type with another name or format
        at = rng.choice(fmts)
        twin = bytearray(data[at : at + 89])
        twin[9:25] = rng.choice([b"Q".ljust(16, b"\0"), b"QBfff".ljust(16, b"\0"), b"".ljust(16, b"\0")])
        return data[:at] + bytes(twin) + data[at:]
    if fmts and kind == 3:  # an FMT's type id
        at = rng.choice(fmts)
        return _put(data, at + 3, "<B", rng.randrange(256))
    return data[: rng.randrange(len(data))]


def dataflash_text_mutate(data: bytes, rng: random.Random) -> bytes:
    lines = data.split(b"\n")
    fmts = [k for k, ln in enumerate(lines) if ln.startswith(b"FMT")]
    if not fmts:
        return data
    k = rng.choice(fmts)
    cells = lines[k].split(b", ")
    if len(cells) > 4:
        spot = rng.choice([1, 2, 3, 4])
        cells[spot] = rng.choice([c.encode() for c in COUNTS] + [b"QQQQQQQQQQQQQQQQQQQQQQ", b"a", b"", b"IMU"])
    if rng.random() < 0.3:
        lines.insert(k, b", ".join(cells))  # given twice
    else:
        lines[k] = b", ".join(cells)
    return b"\n".join(lines)


# -- ROS 1 bags and MCAP ----------------------------------------------------------------------


def ros_seeds(folder: Path) -> dict[str, bytes]:
    """A ROS 1 bag with lz4 chunks, one with bz2 chunks, and an MCAP file with zstd chunks."""
    from rosbags.rosbag1 import Writer as Writer1

    from tests import ros_writer

    t, xyz = _faces(240)
    topic = {"/imu": ros_writer.Messages(t * 1000, 9.80665 * xyz, 0.01 * xyz)}
    out = {
        "log.bag": ros_writer.write(folder / "lz4.bag", "ros1", topic, compressed=True).read_bytes(),
        "log.mcap": ros_writer.write(folder / "zstd.mcap", "plain", topic, compressed=True).read_bytes(),
    }
    plain = ros_writer.write(folder / "plain.bag", "ros1", topic).read_bytes()
    out["bz2.bag"] = _rechunked(plain, folder / "bz2.bag", Writer1.CompressionFormat.BZ2)
    return out


def _rechunked(plain: bytes, path: Path, how: object) -> bytes:
    """A ROS 1 bag's messages written again with chunks of ``how`` (rosbags' writer)."""
    from rosbags.rosbag1 import Reader, Writer

    source = path.with_suffix(".src.bag")
    source.write_bytes(plain)
    writer = Writer(path)
    writer.set_compression(how)  # type: ignore[arg-type]
    writer.chunk_threshold = 1 << 12
    with Reader(source) as reader, writer:
        conns = {
            c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
            for c in reader.connections
        }
        for c, t, raw in reader.messages():
            writer.write(conns[c.id], t, raw)
    return path.read_bytes()


def _bag_records(data: bytes) -> list[tuple[int, int, dict[str, tuple[int, bytes]], int]]:
    """Each top-level record of a ROS 1 bag: (first byte, header length, fields by name with the
    byte each value starts at, data length)."""
    out, at = [], data.find(b"\n") + 1
    while at + 4 <= len(data):
        (head,) = struct.unpack_from("<I", data, at)
        if at + 8 + head > len(data):
            break
        fields, k = {}, at + 4
        while k < at + 4 + head:
            (flen,) = struct.unpack_from("<I", data, k)
            name, _, value = data[k + 4 : k + 4 + flen].partition(b"=")
            fields[name.decode("ascii", "replace")] = (k + 4 + len(name) + 1, value)
            k += 4 + flen
        (size,) = struct.unpack_from("<I", data, at + 4 + head)
        out.append((at, head, fields, size))
        at += 8 + head + size
    return out


def bag_mutate(data: bytes, rng: random.Random) -> bytes:
    records = _bag_records(data)
    chunks = [r for r in records if r[2].get("op", (0, b""))[1] == b"\x05"]
    kind = rng.randrange(6)
    if kind == 0 and chunks:  # a chunk's declared (uncompressed) size
        at, head, fields, size = rng.choice(chunks)
        where = fields["size"][0]
        return _put(data, where, "<I", rng.choice([0, 1, 2**31 - 1, 2**32 - 1, fields_size(fields) * 1000]))
    if kind == 1 and chunks:  # the compression a chunk claims
        at, head, fields, size = rng.choice(chunks)
        where, value = fields["compression"]
        claim = rng.choice([b"bz2", b"lz4", b"non", b"zst", b"gz\x00"])[: len(value)].ljust(len(value), b"x")
        return data[:where] + claim + data[where + len(value) :]
    if kind == 2 and chunks:  # a chunk's data replaced by a bomb of its compression
        at, head, fields, size = rng.choice(chunks)
        how = fields["compression"][1]
        bomb = _bomb(how.decode("ascii", "replace"))
        begin = at + 8 + head
        new = data[: at + 4 + head] + struct.pack("<I", len(bomb)) + bomb + data[begin + size :]
        return new
    if kind == 3 and records:  # a record's header or data length
        at, head, fields, size = rng.choice(records)
        where = at if rng.random() < 0.5 else at + 4 + head
        return _put(data, where, "<I", _number(rng, 4))
    if kind == 4 and records:  # the bag header's index_pos, or a field's length
        at, head, fields, size = records[0]
        if "index_pos" in fields:
            return _put(data, fields["index_pos"][0], "<Q", rng.choice([*HUGE, len(data) // 2]))
    if kind == 5 and records:  # a field dropped: op, conn, time
        at, head, fields, size = rng.choice(records)
        name = rng.choice(sorted(fields))
        where, value = fields[name]
        start = where - len(name) - 1 - 4
        return data[:start] + struct.pack("<I", len(name) + 1 + len(value)) + b"X" * len(name) + b"=" + data[where:]
    return data[: rng.randrange(len(data))]


def fields_size(fields: dict[str, tuple[int, bytes]]) -> int:
    value = fields.get("size", (0, b"\0\0\0\0"))[1]
    return int(struct.unpack("<I", value[:4].ljust(4, b"\0"))[0]) if value else 0


def _mcap_records(data: bytes) -> list[tuple[int, int, int]]:
    """Each top-level MCAP record: (first byte, opcode, content length)."""
    out, at = [], 8
    while at + 9 <= len(data):
        op, size = data[at], struct.unpack_from("<Q", data, at + 1)[0]
        out.append((at, op, size))
        if at + 9 + size > len(data):
            break
        at += 9 + size
    return out


def mcap_mutate(data: bytes, rng: random.Random) -> bytes:
    records = _mcap_records(data)
    by = {op: [r for r in records if r[1] == op] for op in (3, 4, 6, 2)}
    kind = rng.randrange(6)
    if kind == 0 and records:  # a record's length
        at, _, _ = rng.choice(records)
        return _put(data, at + 1, "<Q", rng.choice([*HUGE, len(data)]))
    if kind == 1 and (by[3] or by[4]):  # a schema's or channel's string length
        at, op, _ = rng.choice(by[3] + by[4])
        return _put(data, at + 9 + (2 if op == 3 else 4), "<I", rng.choice([*HUGE[:7], 2**32 - 1]))
    if kind == 2 and by[6]:  # a chunk's uncompressed size (at 16) or its compressed records' length
        at, _, _ = rng.choice(by[6])
        (clen,) = struct.unpack_from("<I", data, at + 9 + 28)
        where = at + 9 + 16 if rng.random() < 0.5 else at + 9 + 32 + clen
        return _put(data, where, "<Q", rng.choice(HUGE))
    if kind == 3 and by[6]:  # the chunk's compression claim
        at, _, _ = rng.choice(by[6])
        (clen,) = struct.unpack_from("<I", data, at + 9 + 28)
        claim = rng.choice(["", "lz4", "zstd", "gzip", "bz2", "x" * 40])
        start = at + 9 + 28
        new = data[:start] + struct.pack("<I", len(claim)) + claim.encode() + data[start + 4 + clen :]
        return _put(new, at + 1, "<Q", struct.unpack_from("<Q", data, at + 1)[0] + len(claim) - clen)
    if kind == 4 and by[6]:  # a chunk's records replaced by a zstd bomb, its sizes made to agree
        at, _, size = rng.choice(by[6])
        (clen,) = struct.unpack_from("<I", data, at + 9 + 28)
        bomb = _bomb("zstd")
        body = bytearray(data[at + 9 : at + 9 + size])
        start = 28 + 4 + clen
        struct.pack_into("<Q", body, 16, rng.choice([1 << 32, 64, len(bomb)]))  # declared: a lie, or small
        new_body = bytes(body[:start]) + struct.pack("<Q", len(bomb)) + bomb
        head = data[:at] + bytes([6]) + struct.pack("<Q", len(new_body))
        return head + new_body + data[at + 9 + size :]
    return data[: rng.randrange(len(data))]


# -- compressed CSV ---------------------------------------------------------------------------


def compressed_seeds(text: bytes) -> dict[str, bytes]:
    from backports import zstd

    return {
        "log.csv.gz": gzip.compress(text),
        "log.csv.bz2": bz2.compress(text),
        "log.csv.xz": lzma.compress(text),
        "log.csv.zst": zstd.compress(text),
    }


def compressed_mutate(data: bytes, rng: random.Random) -> bytes:
    kind = rng.randrange(3)
    if kind == 0:  # the header's bytes (flags, sizes, the frame descriptor)
        at = rng.randrange(min(24, len(data)))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1 :]
    if kind == 1:  # a bomb of the same kind: gigabytes of one line, no line end
        how = {b"\x1f\x8b": "gzip", b"BZ": "bz2", b"\xfd7": "xz", b"(\xb5": "zstd"}.get(data[:2], "gzip")
        return _bomb(how)
    return data[: rng.randrange(len(data))]


# -- shared -----------------------------------------------------------------------------------

#: Bytes of zeros a bomb inflates to.
BOMB = 4 << 30
_BOMBS: dict[str, bytes] = {}


def _bomb(how: str) -> bytes:
    """``BOMB`` bytes of zeros compressed by ``how`` (bz2, lz4, zstd, gzip, xz), made once."""
    if how not in _BOMBS:
        _BOMBS[how] = _compress_zeros(how)
    return _BOMBS[how]


def _compress_zeros(how: str) -> bytes:
    block = bytes(1 << 24)
    if how == "zstd":
        from backports import zstd  # (rosbags' own dependency; Python 3.14's compression.zstd)

        z = zstd.ZstdCompressor(level=1)
        return b"".join(z.compress(block) for _ in range(BOMB // len(block))) + z.flush()
    if how == "lz4":
        import lz4.frame  # type: ignore[import-untyped]

        c = lz4.frame.LZ4FrameCompressor()
        parts = [c.begin()] + [c.compress(block) for _ in range(BOMB // len(block) // 16)] + [c.flush()]
        return b"".join(parts)  # (lz4's ratio is 255:1: a quarter of a gigabyte, not four)
    if how == "gzip":
        out = io.BytesIO()
        with gzip.GzipFile(fileobj=out, mode="wb", compresslevel=1) as g:
            for _ in range(BOMB // len(block) // 4):
                g.write(block)
        return out.getvalue()
    maker = lzma.LZMACompressor(preset=0) if how == "xz" else bz2.BZ2Compressor(1)
    parts = [maker.compress(block) for _ in range(BOMB // len(block) // 4)]  # a gigabyte
    return b"".join(parts) + maker.flush()


def _faces(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Six faces rested on in turn, ``rows`` readings each at 100 Hz (times in µs), in g."""
    rng = np.random.default_rng(5)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    xyz = np.repeat(faces, rows, axis=0) + rng.normal(0, 0.002, (6 * rows, 3)) + [0.01, -0.02, 0.015]
    t = 1_000_000 + np.arange(len(xyz), dtype=np.int64) * 10_000
    return t, xyz
