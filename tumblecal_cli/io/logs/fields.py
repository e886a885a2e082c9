"""What the binary log readers (io.logs.ulog, io.logs.dataflash) share: the columns a sensor's readings
are recorded as, gathering fixed-layout fields from known places in a file a chunk at a time
(the log is never in memory whole), and a clock that must go forward."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import BoolArray, FloatArray, IntArray
from tumblecal_cli.errors import InputError

#: Bytes read at a time.
CHUNK = 1 << 22
#: A clock that goes back this often is not a stray sample but two sessions (exit 2).
BACK_SHARE = 0.01
#: The columns a calibration records for each sensor (what a segment's block CSV is headed by).
NAMES = {
    "accelerometer": ("acc_x", "acc_y", "acc_z"),
    "gyroscope": ("gyr_x", "gyr_y", "gyr_z"),
    "magnetometer": ("mag_x", "mag_y", "mag_z"),
}


#: Past this many digits a count, a length or an id is reported as written, not read as a number.
DIGITS = 18


def ascii_int(text: str) -> int | None:
    """``text`` as a whole number when it is one written in ASCII digits, else None; past ``DIGITS``
    digits, ``10**DIGITS`` (more than any count, length or id of a log). Not int(): str.isdigit
    takes '²' (which int() refuses) and int() takes '٣' for 3, ' 3', '+3' and '3_0', and it
    refuses a number of over 4300 digits with a ValueError."""
    if not (text.isascii() and text.isdigit()):
        return None
    digits = text.lstrip("0") or "0"
    return int(digits) if len(digits) <= DIGITS else 10**DIGITS


def shown(text: str) -> str:
    """``text`` as a message quotes it: repr'd, and cut to its first characters when long (a
    number of 5000 digits)."""
    return repr(text) if len(text) <= 24 else f"{text[:12]!r}... ({len(text)} characters)"


def gather(
    path: str, places: NDArray[np.int64], fields: Mapping[str, tuple[str, int]], names: list[str]
) -> dict[str, FloatArray]:
    """The fields ``names`` (each a numpy type and a byte offset from its place, in ``fields``)
    of the records that start at ``places`` (sorted), read a chunk of the file at a time: a
    record view at every byte of the chunk, indexed by the places; each field as float64 (exact
    for every type a log's field has but a 64-bit integer past 2**53, which no timestamp in µs
    reaches)."""
    offsets = [fields[n][1] for n in names]
    span = max(o + np.dtype(fields[n][0]).itemsize for n, o in zip(names, offsets, strict=True))
    record = np.dtype({"names": names, "formats": [fields[n][0] for n in names], "offsets": offsets, "itemsize": span})
    out = {n: np.empty(len(places)) for n in names}
    with open(path, "rb") as f:
        i = 0
        while i < len(places):
            start = int(places[i])
            j = max(int(np.searchsorted(places, start + CHUNK - span, side="right")), i + 1)
            f.seek(start)
            chunk = f.read(int(places[j - 1]) + span - start)
            if len(chunk) < int(places[j - 1]) + span - start:
                raise InputError("the log changed while it was read", file=path)
            view = np.ndarray((len(chunk) - span + 1,), dtype=record, buffer=chunk, strides=(1,))
            rows = view[places[i:j] - start]
            with np.errstate(invalid="ignore"):  # a signalling NaN's bits (a corrupt float) read as NaN
                for n in names:
                    out[n][i:j] = rows[n]
            i = j
    return out


def forward(
    path: str,
    key: str,
    clock: FloatArray | IntArray,
    keep: BoolArray,
    notes: list[str],
    per_second: float = 1e6,
    words: tuple[str, str] = ("sample", "timestamp"),
) -> BoolArray:
    """The samples to keep so that the clock (``per_second`` ticks a second) never goes back: a
    lone sample out of order (a corrupt one: its clock before its neighbours', or after both) is
    skipped with a note; a clock that goes back more often than that, or for good (two
    sessions, a simulation restarted), is exit 2. ``words``: what a sample and its stamp are
    called in the messages (a bag's: message, header stamp)."""
    one, stamp = words
    t = clock[keep]
    where = np.flatnonzero(keep)
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size == 0:
        return np.ones(len(clock), dtype=bool)
    drop = []
    for j in back + 1:  # t[j] < t[j - 1]: drop t[j - 1] if it is the odd one (a spike), else t[j]
        spike = t[j] >= t[j - 2] if j >= 2 else not (len(t) > 2 and t[2] >= t[0])
        drop.append(j - 1 if spike else j)
    mask = np.ones(len(t), dtype=bool)
    mask[drop] = False
    steps = np.diff(t[mask])
    if (steps < 0).any() or len(drop) > max(1, BACK_SHARE * len(t)):
        k = int(back[0]) + 1
        raise InputError(
            f"{key}: the {stamp}s go back at {one} {int(where[k]) + 1} ({t[k] / per_second:.6f} s after "
            f"{t[k - 1] / per_second:.6f} s), {len(back)} times in {len(t)} {one}s: not a stray corrupt {one}",
            file=path,
            hint=f"give --rate HZ to read the {one}s by their rate instead of their {stamp}s",
        )
    notes.append(
        f"{path}: {key}: {len(drop)} {one}s whose {stamp} went back skipped (a corrupt {one}; the first at "
        f"{one} {int(where[drop[0]]) + 1})"
    )
    out = np.ones(len(clock), dtype=bool)
    out[where[~mask]] = False
    return out
