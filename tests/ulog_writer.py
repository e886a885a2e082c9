"""A small writer of PX4 ULog files in the real format (docs.px4.io "ULog File Format"), for
tests and the benchmark: the header, the flag bits, the formats PX4 1.12+ logs for
``sensor_accel`` and ``sensor_gyro`` (copied from real logs, tests/data/px4), subscriptions,
data messages in time order, sync markers and logged strings."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

MAGIC = b"ULog\x01\x12\x35"
SYNC = b"\x2f\x73\x13\x20\x25\x0c\xbb\x12"
#: The formats of PX4 1.12's logs (as in tests/data/px4/robologs_fmu_v5.ulg).
FORMATS = {
    "sensor_accel": "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;"
    "float temperature;uint32_t error_count;uint8_t[3] clip_counter;uint8_t samples;uint8_t[4] _padding0;",
    "sensor_gyro": "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;"
    "float temperature;uint32_t error_count;uint8_t samples;uint8_t[7] _padding0;",
}
#: Each topic's sample after the msg_id: timestamp, timestamp_sample, device_id, x, y, z,
#: temperature, error_count, then the rest (zeros) but the trailing padding, which PX4's logger
#: leaves out (a real log's sensor_accel messages are 46 bytes: msg_id and 44).
_SAMPLE = struct.Struct("<QQIffffI")
_TAIL = {"sensor_accel": 4, "sensor_gyro": 1}


def message(kind: str, body: bytes) -> bytes:
    return struct.pack("<HB", len(body), ord(kind)) + body


def header(start_us: int = 0) -> bytes:
    """The file header and the flag bits message (no appended data)."""
    return MAGIC + b"\x01" + struct.pack("<Q", start_us) + message("B", bytes(8) + bytes(8) + bytes(24))


def definitions(topics: Sequence[str] = ("sensor_accel",)) -> bytes:
    out = message("I", bytes([len("char[9] sys_name")]) + b"char[9] sys_nameULogTests")
    for name in topics:
        out += message("F", f"{name}:{FORMATS[name]}".encode())
    return out


def subscribe(msg_id: int, name: str, instance: int = 0) -> bytes:
    return message("A", struct.pack("<BH", instance, msg_id) + name.encode())


def sample(msg_id: int, name: str, t_us: int, xyz: Sequence[float], temperature: float = 25.0) -> bytes:
    """One data message of ``name`` (sensor_accel or sensor_gyro) stamped ``t_us`` (both stamps)."""
    body = struct.pack("<H", msg_id) + _SAMPLE.pack(t_us + 150, t_us, 0x6A000A, *xyz, temperature, 0)
    return message("D", body + bytes(_TAIL[name]))


def samples(
    msg_id: int, name: str, t_us: NDArray[np.int64], xyz: NDArray[np.float64], temperature: NDArray[np.float64]
) -> list[bytes]:
    """The data messages of a whole stream, fast: a structured array's rows, each one message."""
    layout = np.dtype(
        [
            ("size", "<u2"),
            ("kind", "u1"),
            ("id", "<u2"),
            ("t", "<u8"),
            ("ts", "<u8"),
            ("dev", "<u4"),
            ("xyz", "<f4", 3),
            ("temp", "<f4"),
            ("err", "<u4"),
            ("tail", "u1", _TAIL[name]),
        ]
    )
    rows = np.zeros(len(t_us), dtype=layout)
    rows["size"], rows["kind"], rows["id"] = layout.itemsize - 3, ord("D"), msg_id
    rows["t"], rows["ts"], rows["dev"] = t_us + 150, t_us, 0x6A000A
    rows["xyz"], rows["temp"] = xyz, temperature
    data = rows.tobytes()
    size = layout.itemsize
    return [data[i : i + size] for i in range(0, len(data), size)]


def write(
    path: Path,
    t_us: NDArray[np.int64],
    xyz: NDArray[np.float64],
    temperature: NDArray[np.float64] | None = None,
    *,
    instances: int = 1,
    sync_every: int = 0,
) -> Path:
    """A ULog of ``sensor_accel`` samples (``instances`` of it, the same readings each, offset a
    little in time), in time order, a sync marker every ``sync_every`` samples (0: none)."""
    temp = np.full(len(t_us), 25.0) if temperature is None else temperature
    parts = [header(int(t_us[0]) - 1000), definitions()]
    parts += [subscribe(10 + k, "sensor_accel", k) for k in range(instances)]
    streams = [samples(10 + k, "sensor_accel", t_us + 7 * k, xyz, temp) for k in range(instances)]
    body: list[bytes] = []
    for i in range(len(t_us)):
        body.extend(s[i] for s in streams)
        if sync_every and (i + 1) % sync_every == 0:
            body.append(message("S", SYNC))
    path.write_bytes(b"".join(parts + body))
    return path


def float32(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """``values`` as a ULog holds them (float32), back in float64: what a CSV must hold to match."""
    return values.astype(np.float32).astype(np.float64)


def write_streams(path: Path, streams: Sequence[tuple[str, int, NDArray[np.int64], NDArray[np.float64]]]) -> Path:
    """A ULog of several topic instances, each (``sensor_accel`` or ``sensor_gyro``, instance,
    stamps in µs, readings), their samples merged in time order (a logger writes each as it comes)."""
    names = tuple(dict.fromkeys(name for name, _, _, _ in streams))
    parts = [header(int(min(t[0] for _, _, t, _ in streams)) - 1000), definitions(names)]
    parts += [subscribe(10 + k, name, instance) for k, (name, instance, _, _) in enumerate(streams)]
    stamps, messages = [], []
    for k, (name, _, t_us, xyz) in enumerate(streams):
        stamps.append(t_us)
        messages += samples(10 + k, name, t_us, xyz, np.full(len(t_us), 25.0))
    order = np.argsort(np.concatenate(stamps), kind="stable")
    path.write_bytes(b"".join(parts + [messages[i] for i in order]))
    return path
