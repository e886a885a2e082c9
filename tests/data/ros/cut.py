"""Cut the real bags of ../shared/realdata/logs down to the copies in this folder (run by hand:
`.venv/bin/python tests/data/ros/cut.py ../shared/realdata/logs`). Each copy holds the real
messages of a stretch of the original, byte for byte, with their record times and the original
connections' message definitions, written again by rosbags' writers (ROS 1: the same chunk
compression as the original's, bz2; ROS 2: MCAP storage, as the derived original)."""

from __future__ import annotations

import sys
from pathlib import Path

from rosbags.interfaces import ConnectionExtRosbag1
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Reader as Reader2
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2

HERE = Path(__file__).resolve().parent
#: (original, copy, seconds after the bag's start kept: from, to)
ROS1 = [
    ("robot_localization_test1/test1.bag", "test1_cut.bag", (236.0, 248.0)),
    ("robot_localization_test2/test2.bag", "test2_cut.bag", (0.0, 6.0)),
]
ROS2 = ("ros2_derived_robot_localization_test1/test1_mcap", "test1_mcap_cut", (236.0, 248.0))


def cut_ros1(src: Path, dst: Path, window: tuple[float, float]) -> None:
    dst.unlink(missing_ok=True)
    writer = Writer1(dst)
    writer.set_compression(Writer1.CompressionFormat.BZ2)
    writer.chunk_threshold = 1 << 16  # several chunks, as a longer recording has
    with Reader1(src) as reader, writer:
        made = {}
        for c in reader.connections:
            ext = c.ext
            assert isinstance(ext, ConnectionExtRosbag1)
            made[c.id] = writer.add_connection(
                c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest, callerid=ext.callerid, latching=ext.latching
            )
        start = reader.start_time
        lo, hi = (start + int(s * 1e9) for s in window)
        for c, t, data in reader.messages(start=lo, stop=hi):
            writer.write(made[c.id], t, data)


def cut_ros2(src: Path, dst: Path, window: tuple[float, float]) -> None:
    import shutil

    shutil.rmtree(dst, ignore_errors=True)
    with Reader2(src) as reader:
        writer = Writer2(dst, version=9, storage_plugin=StoragePlugin.MCAP)
        with writer:
            made = {
                c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, rihs01=c.digest)
                for c in reader.connections
            }
            start = reader.start_time
            lo, hi = (start + int(s * 1e9) for s in window)
            for c, t, data in reader.messages(start=lo, stop=hi):
                writer.write(made[c.id], t, data)


if __name__ == "__main__":
    logs = Path(sys.argv[1])
    for original, copy, window in ROS1:
        cut_ros1(logs / original, HERE / copy, window)
    cut_ros2(logs / ROS2[0], HERE / ROS2[1], ROS2[2])
