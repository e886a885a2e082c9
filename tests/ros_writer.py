"""ROS bags written for the tests by rosbags' own writers and serializers: ROS 1 bags, ROS 2
bags (sqlite3 or MCAP storage) and plain MCAP files holding ``sensor_msgs/Imu`` and
``sensor_msgs/MagneticField`` topics (and an odometry topic, as a robot's bag has)."""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

IMU = "sensor_msgs/msg/Imu"
MAG = "sensor_msgs/msg/MagneticField"
ODOM = "nav_msgs/msg/Odometry"
KINDS = ("ros1", "sqlite3", "mcap", "plain")
ROS1 = get_typestore(Stores.ROS1_NOETIC)
ROS2 = get_typestore(Stores.ROS2_HUMBLE)


@dataclass
class Messages:
    """One topic's messages: header stamps (ns), the readings (an Imu's linear acceleration, a
    MagneticField's field), an Imu's angular velocity, the record times (default: the stamps
    and 2 ms), and the frame_id."""

    stamps: NDArray[np.int64]
    xyz: NDArray[np.float64]
    gyro: NDArray[np.float64] | None = None
    msgtype: str = IMU
    received: NDArray[np.int64] | None = None
    frame: str = "imu_link"


def serialize(store: Typestore, msgtype: str, stamp: int, frame: str, xyz: object, gyro: object) -> bytes:
    """One message as the store's ROS version serializes it (ROS 1, or CDR little-endian)."""
    types = store.types
    sec, nsec = divmod(int(stamp), 1_000_000_000)
    stamp_msg = types["builtin_interfaces/msg/Time"](sec, nsec)
    if store is ROS1:
        header = types["std_msgs/msg/Header"](0, stamp_msg, frame)
    else:
        header = types["std_msgs/msg/Header"](stamp_msg, frame)
    vector, zeros = types["geometry_msgs/msg/Vector3"], np.zeros(9)
    if msgtype == MAG:
        msg = types[MAG](header, vector(*xyz), zeros)  # type: ignore[misc]
    elif msgtype == IMU:
        quaternion = types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)
        msg = types[IMU](header, quaternion, zeros, vector(*gyro), zeros, vector(*xyz), zeros)  # type: ignore[misc]
    else:
        return bytes(8)
    data = store.serialize_ros1(msg, msgtype) if store is ROS1 else store.serialize_cdr(msg, msgtype)
    return bytes(data)


def write(
    path: Path, kind: str, topics: Mapping[str, Messages], *, odometry: bool = True, compressed: bool = False
) -> Path:
    """``topics`` written as a ``kind`` bag at ``path`` (ros1: a .bag file; sqlite3, mcap: a ROS 2
    bag folder; plain: an MCAP file), every message in record-time order; ``compressed``: a ROS 1
    bag's chunks lz4 (16 KiB), an MCAP file's chunks zstd; with ``odometry`` an empty-bodied
    nav_msgs/Odometry topic beside them (a type not read)."""
    store = ROS1 if kind == "ros1" else ROS2
    rows = []
    for name, m in topics.items():
        received = m.stamps + 2_000_000 if m.received is None else m.received
        gyro = m.gyro if m.gyro is not None else np.zeros_like(m.xyz)
        for k in range(len(m.stamps)):
            rows.append(
                (int(received[k]), name, serialize(store, m.msgtype, int(m.stamps[k]), m.frame, m.xyz[k], gyro[k]))
            )
    rows.sort(key=lambda r: r[0])
    types = {name: m.msgtype for name, m in topics.items()}
    if odometry:
        types["/odom"] = ODOM
    if kind == "ros1":
        w1 = Writer1(path)
        if compressed:
            w1.set_compression(Writer1.CompressionFormat.LZ4)
            w1.chunk_threshold = 1 << 14
        with w1:
            c1 = {name: w1.add_connection(name, msgtype, typestore=ROS1) for name, msgtype in types.items()}
            for t, name, data in rows:
                w1.write(c1[name], t, data)
        return path
    folder = path.with_suffix("") if kind == "plain" else path
    storage = StoragePlugin.SQLITE3 if kind == "sqlite3" else StoragePlugin.MCAP
    w2 = Writer2(folder, version=9, storage_plugin=storage)
    if compressed:
        w2.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with w2:
        c2 = {name: w2.add_connection(name, msgtype, typestore=ROS2) for name, msgtype in types.items()}
        for t, name, data in rows:
            w2.write(c2[name], t, data)
    if kind == "plain":
        shutil.move(str(next(folder.glob("*.mcap"))), path)
        shutil.rmtree(folder)
    return path
