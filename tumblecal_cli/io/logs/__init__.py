"""Autopilot and robot logs, each a reader registered in ``io.sources``. Its modules:

- ``reader``: ``LogReader``, what every log reader shares: its index of the log kept while the
  file is unchanged, the refusal of a label column, and the note saying which stream was read.
- ``fields``: what the binary readers share: a sensor's columns, fixed-layout fields gathered
  a chunk at a time, a clock that must go forward.
- ``ulog``: PX4 ULog (``.ulg``).
- ``dataflash``: ArduPilot DataFlash binary logs (``.bin``).
- ``dftext``: ArduPilot DataFlash logs in their text form (``.log``).
- ``ros``: ROS 1 bags, ROS 2 bags and MCAP files (the optional extra ``tumblecal[ros]``).
- ``bagfile``: a bag's and an MCAP file's bytes read without trusting them: chunks inflated
  within their declared sizes and --max-spool, and the walks of a recording cut short.

Here too, the bound on what one pass over a log may inflate (``inflating_at_most``: --max-spool,
which ``ros``'s chunks are held to), set by the pipeline without importing a reader.

Here, each format as the registry knows it before its module is imported (``FORMATS``): its
kind, its module, and how it claims a file (its first bytes, or a function of the path and
those bytes, beside the format's row). This module imports nothing but the standard library:
``tumblecal --help`` and the commands on CSV captures read it, never a reader's module.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass

#: What ``inflating_at_most`` gives: the most one pass over a log's file inflates (None: MAX_SPOOL).
_INFLATE: ContextVar[int | None] = ContextVar("tumblecal_inflate_limit", default=None)


@contextlib.contextmanager
def inflating_at_most(limit: int | None) -> Iterator[None]:
    """Logs read inside inflate at most ``limit`` bytes a pass over a file (--max-spool, as
    read_twice is given it; None: io.outputs.MAX_SPOOL)."""
    token = _INFLATE.set(limit)
    try:
        yield
    finally:
        _INFLATE.reset(token)


def inflate_limit() -> int | None:
    """The bound ``inflating_at_most`` set (None: none given)."""
    return _INFLATE.get()


@dataclass(frozen=True)
class LogFormat:
    """A kind of log, and the module whose ``READER`` reads it (imported only when a file it
    claims is read). It claims a file by its first bytes (``magic``) or by ``claim`` (a function
    of the path and those bytes: a bag that is a folder). ``kind`` names the files in messages;
    ``extra`` is the pip extra that installs the packages in ``needs``: without them, reading
    such a file is exit 2 saying ``pip install 'tumblecal[extra]'``."""

    kind: str
    module: str
    magic: tuple[bytes, ...] = ()
    claim: Callable[[str, bytes], bool] | None = None
    extra: str | None = None
    needs: tuple[str, ...] = ()

    def claims(self, path: str, head: bytes) -> bool:
        """Whether ``path``, whose first bytes are ``head`` (b"" for a folder), is a log of this kind."""
        if self.claim is not None:
            return self.claim(path, head)
        return any(head.startswith(m) for m in self.magic)


ULOG = LogFormat("PX4 ULog", "tumblecal_cli.io.logs.ulog", magic=(b"ULog\x01\x12\x35",))

DATAFLASH = LogFormat("ArduPilot DataFlash log", "tumblecal_cli.io.logs.dataflash", magic=(b"\xa3\x95\x80",))


def dataflash_text(path: str, head: bytes) -> bool:
    """An ArduPilot DataFlash log in its text form: its first line an FMT line."""
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"FMT,")


DFTEXT = LogFormat("ArduPilot DataFlash text log", "tumblecal_cli.io.logs.dftext", claim=dataflash_text)


def ros_claim(path: str, head: bytes) -> bool:
    """A ROS 1 bag or an MCAP file by its first bytes, a ROS 2 bag's sqlite3 file (``.db3``), or a
    ROS 2 bag's folder (its metadata.yaml, or the .db3 or .mcap files of a recording cut short)."""
    if head.startswith((b"#ROSBAG V", b"\x89MCAP0\r\n")):
        return True
    if head or not os.path.isdir(path):
        return head.startswith(b"SQLite format 3\x00") and path.endswith(".db3")
    try:
        names = os.listdir(path)
    except OSError:
        return False
    return "metadata.yaml" in names or any(n.endswith((".db3", ".mcap")) for n in names)


ROS = LogFormat("ROS bag or MCAP file", "tumblecal_cli.io.logs.ros", claim=ros_claim, extra="ros", needs=("rosbags",))

#: The formats of the logs read, in the order the registry asks them (io.sources.READERS).
FORMATS = (ULOG, DATAFLASH, DFTEXT, ROS)
