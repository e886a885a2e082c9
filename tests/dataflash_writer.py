"""A small writer of ArduPilot DataFlash logs in the real format (libraries/AP_Logger/LogStructure.h),
for tests and the benchmark: the FMT of FMT, the FMTs of PARM, IMU, ACC, GYR and MAG as recent
ArduPilot logs them (an ``I`` instance field; ACC and GYR with ``SampleUS``), PARM messages, and
the sensor messages in time order, written a frame (one time step of every stream) at a time with
numpy. Also the text form of a binary log (``text_of``: one line a message, as pymavlink's
DFReader_text reads it), made with pymavlink's own reading of the binary log."""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tests.ulog_writer import float32 as float32  # values as a log holds them (float32)

HEAD = b"\xa3\x95"
#: Each message type written: its id, format and columns (as ArduPilot 4.x logs them).
TYPES = {
    "FMT": (128, "BBnNZ", "Type,Length,Name,Format,Columns"),
    "PARM": (129, "QNf", "TimeUS,Name,Value"),
    "IMU": (130, "QBffffffIIfBBHH", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz"),
    "ACC": (131, "QBQfff", "TimeUS,I,SampleUS,AccX,AccY,AccZ"),
    "GYR": (132, "QBQfff", "TimeUS,I,SampleUS,GyrX,GyrY,GyrZ"),
    "MAG": (133, "QBhhhhhhhhhBI", "TimeUS,I,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOX,MOY,MOZ,Health,S"),
    "MSG": (134, "QZ", "TimeUS,Message"),
}
_STRUCT = {"B": "B", "b": "b", "h": "h", "H": "H", "i": "i", "I": "I", "f": "f", "Q": "Q", "q": "q", "d": "d"}
_STRUCT |= {"n": "4s", "N": "16s", "Z": "64s"}
_NUMPY = {"B": "u1", "b": "i1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4", "f": "<f4", "Q": "<u8", "d": "<f8"}


def layout(name: str) -> str:
    return "<" + "".join(_STRUCT[c] for c in TYPES[name][1])


def length(name: str) -> int:
    return 3 + struct.calcsize(layout(name))


def message(name: str, *values: object) -> bytes:
    return HEAD + bytes([TYPES[name][0]]) + struct.pack(layout(name), *values)


def fmt(name: str) -> bytes:
    kind, chars, columns = TYPES[name]
    return message("FMT", kind, length(name), name.encode(), chars.encode(), columns.encode())


def header(params: Mapping[str, float] | None = None, t_us: int = 1_000_000) -> bytes:
    """The FMTs of every type, a version message, and ``params`` as PARM messages."""
    out = b"".join(fmt(name) for name in TYPES)
    out += message("MSG", t_us, b"ArduCopter V4.5.0 (tumblecal tests)")
    for key, value in (params or {}).items():
        out += message("PARM", t_us, key.encode(), value)
    return out


def dtype(name: str) -> np.dtype[np.void]:
    """A whole message of ``name`` (header included) as a numpy record."""
    _, chars, columns = TYPES[name]
    fields = [(c, _NUMPY[k]) for k, c in zip(chars, columns.split(","), strict=True)]
    return np.dtype([("h", "u1", (2,)), ("type", "u1"), *fields])


def records(name: str, rows: int, **columns: object) -> NDArray[np.void]:
    """``rows`` messages of ``name``, their columns set from ``columns`` (the rest zero)."""
    out = np.zeros(rows, dtype=dtype(name))
    out["h"] = np.frombuffer(HEAD, dtype=np.uint8)
    out["type"] = TYPES[name][0]
    for key, value in columns.items():
        out[key] = value
    return out


def frames(parts: Sequence[NDArray[np.void]]) -> bytes:
    """Streams of the same number of messages, interleaved: each time step's messages in order."""
    rows = len(parts[0])
    return np.concatenate([p.view(np.uint8).reshape(rows, -1) for p in parts], axis=1).tobytes()


def imu(t_us: NDArray[np.int64], acc: NDArray[np.float64], temperature: NDArray[np.float64], instance: int = 0,
        gyr: NDArray[np.float64] | None = None) -> NDArray[np.void]:  # fmt: skip
    """IMU messages (m/s^2, rad/s, °C) stamped ``t_us``."""
    g = np.zeros_like(acc) if gyr is None else gyr
    return records(
        "IMU", len(t_us), TimeUS=t_us, I=instance, AccX=acc[:, 0], AccY=acc[:, 1], AccZ=acc[:, 2],
        GyrX=g[:, 0], GyrY=g[:, 1], GyrZ=g[:, 2], T=temperature, GH=1, AH=1, GHz=1000, AHz=1000,
    )  # fmt: skip


def write(
    path: Path,
    t_us: NDArray[np.int64],
    acc: NDArray[np.float64],
    temperature: NDArray[np.float64] | None = None,
    *,
    instances: int = 1,
    params: Mapping[str, float] | None = None,
) -> Path:
    """A log of IMU messages (``instances`` of them, the same readings each, 7 µs apart), after
    ``params`` (default: a calibration of zero offsets and unit scales, so the IMU is raw)."""
    temp = np.full(len(t_us), 25.0) if temperature is None else temperature
    given = identity(instances) if params is None else params
    parts = [imu(t_us + 7 * k, acc, temp, k) for k in range(instances)]
    path.write_bytes(header(given, int(t_us[0]) - 1000) + frames(parts))
    return path


def identity(instances: int = 3) -> dict[str, float]:
    """PARM of the accelerometers', gyroscopes' and compasses' calibrations left at their defaults."""
    out: dict[str, float] = {}
    for k in range(instances):
        n = "" if k == 0 else str(k + 1)
        for axis in "XYZ":
            out |= {f"INS_ACC{n}OFFS_{axis}": 0.0, f"INS_ACC{n}SCAL_{axis}": 1.0, f"INS_GYR{n}OFFS_{axis}": 0.0}
            out |= {f"COMPASS_OFS{n}_{axis}": 0.0, f"COMPASS_DIA{n}_{axis}": 1.0, f"COMPASS_ODI{n}_{axis}": 0.0}
    return out


def text_of(binary: Path, out: Path, delimiter: str = ", ") -> Path:
    """The text form of ``binary``, as pymavlink reads it: its FMT lines, then each message a line
    (values as pymavlink gives them: floats to their shortest round-trip digits). Messages with
    text fields that hold the delimiter, or arrays, are left out (not read by tumblecal)."""
    from pymavlink import DFReader

    lines = []
    with DFReader.DFReader_binary(str(binary)) as log:
        messages = []
        while (m := log.recv_msg()) is not None:
            messages.append(m)
    for m in messages:
        f = m.fmt
        if f.name == "FMT":
            values = [m.Type, m.Length, m.Name, m.Format, m.Columns]
        else:
            if "a" in f.format:
                continue
            values = [getattr(m, c) for c in f.columns]
        text = [repr(v) if isinstance(v, float) else str(v) for v in values]
        if f.name != "FMT" and any(delimiter.strip() in t for t in text):
            continue
        lines.append(delimiter.join([f.name, *text]))
    out.write_text("\n".join(lines) + "\n")
    return out
