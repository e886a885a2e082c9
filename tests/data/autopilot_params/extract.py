"""Recreate this folder's parameter lists from the upstream logs (SOURCE.md):

    python tests/data/autopilot_params/extract.py SPARK404_LOG_BIN ROBOLOGS_TEST_ULG

ArduPilot DataFlash: the PARM messages (their layout from the log's own FMT messages: 'N' is
char[16], 'f' float, 'Q' uint64), the last value of each name, as NAME,VALUE lines. PX4 ULog:
the definitions section's 'P' messages (key "type NAME", then the value), as "type NAME VALUE".
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

SIZES = {
    "b": 1,
    "B": 1,
    "h": 2,
    "H": 2,
    "i": 4,
    "I": 4,
    "f": 4,
    "d": 8,
    "n": 4,
    "N": 16,
    "Z": 64,
    "c": 2,
    "C": 2,
    "e": 4,
    "E": 4,
    "L": 4,
    "M": 1,
    "q": 8,
    "Q": 8,
}


def dataflash_params(data: bytes) -> dict[str, float]:
    lengths: dict[int, int] = {128: 89}
    parm: tuple[int, str] | None = None
    out: dict[str, float] = {}
    i = 0
    while i + 3 <= len(data):
        if data[i : i + 2] != b"\xa3\x95" or data[i + 2] not in lengths or i + lengths[data[i + 2]] > len(data):
            i += 1
            continue
        kind = data[i + 2]
        body = data[i + 3 : i + lengths[kind]]
        if kind == 128:
            lengths[body[0]] = body[1]
            if body[2:6].rstrip(b"\0") == b"PARM":
                parm = (body[0], body[6:22].rstrip(b"\0").decode())
        elif parm is not None and kind == parm[0]:
            at = sum(SIZES[c] for c in parm[1][: parm[1].index("N")])
            name = body[at : at + 16].rstrip(b"\0").decode()
            (out[name],) = struct.unpack_from("<f", body, at + 16)
        i += lengths[kind]
    return out


def ulog_params(data: bytes) -> dict[str, tuple[str, float]]:
    assert data[:7] == b"ULog\x01\x12\x35"
    out: dict[str, tuple[str, float]] = {}
    i = 16
    while i + 3 <= len(data):
        size, kind = struct.unpack_from("<HB", data, i)
        if kind == ord("A"):  # the data section starts: the header's parameters are all read
            break
        if kind == ord("P"):
            key_len = data[i + 3]
            kind_name, name = data[i + 4 : i + 4 + key_len].decode().split(" ")
            (value,) = struct.unpack_from("<f" if kind_name == "float" else "<i", data, i + 4 + key_len)
            out[name] = (kind_name, value)
        i += 3 + size
    return out


def main() -> None:
    here = Path(__file__).resolve().parent
    ardupilot = dataflash_params(Path(sys.argv[1]).read_bytes())
    (here / "ardupilot_copter.parm").write_text("".join(f"{k},{v:.9g}\n" for k, v in sorted(ardupilot.items())))
    px4 = ulog_params(Path(sys.argv[2]).read_bytes())
    (here / "px4_fmu_v5.txt").write_text("".join(f"{t} {k} {v:.9g}\n" for k, (t, v) in sorted(px4.items())))


if __name__ == "__main__":
    main()
