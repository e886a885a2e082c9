"""ArduPilot DataFlash logs in their text form (``.log``, as pymavlink's DFReader_text reads it):
one message a line, ``NAME, value, value, ...``, each message type defined
first by an ``FMT`` line (``FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns``; the
columns after the fifth comma), values as the binary form's after its scales (hundredths,
1e-7). Read into io.logs.dataflash's index, so that the streams and their reading are the binary
form's: the log is walked once a chunk at a time keeping each wanted line's place (and its
``I`` field), and a stream's lines are parsed when it is read. What pymavlink skips is skipped
with a note: a line of a type no FMT line defines, a line whose fields do not parse, a last line
cut short. An FMT line whose Type or Length is a number no binary log can hold (over 255, a
Length under 3) is one InputError naming the line and the field; numbers are ASCII digits only.
"""

from __future__ import annotations

import contextlib
import hashlib
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import logs
from tumblecal_cli.io.logs.dataflash import DataflashIndex, DataflashReader, DataflashStream, Format, named
from tumblecal_cli.io.logs.fields import CHUNK, ascii_int, shown

#: The most an instance (``I``) is: a byte in the binary form (LogStructure.h logs it as ``B``).
MOST_INSTANCE = 255


@dataclass
class _TextWalk:
    """The state of one walk through a text log: the formats seen by name, each wanted message's
    line places (and its instance where the format has an ``I`` column), the parameters, and what
    was skipped."""

    name: str = ""
    formats: dict[str, Format] = field(default_factory=dict)
    places: dict[tuple[str, int], list[int]] = field(default_factory=dict)
    params: dict[str, tuple[float, float]] = field(default_factory=dict)
    param_at: dict[str, int] = field(default_factory=dict)
    unknown: dict[str, int] = field(default_factory=dict)
    streams: dict[str, tuple[str, int | None] | None] = field(default_factory=dict)
    bad: int = 0
    notes: list[str] = field(default_factory=list)

    def line(self, text: bytes, at: int, number: int) -> None:
        """One line of the log (line ``number``), starting at byte ``at``."""
        name = text[: text.find(b",")].strip().decode("ascii", "replace") if b"," in text else ""
        if not name:
            return
        if name == "FMT":
            self.define(text, number)
            return
        fmt = self.formats.get(name)
        if fmt is None:
            self.unknown[name] = self.unknown.get(name, 0) + 1
        elif name == "PARM":
            self.param(fmt, text, number)
        elif (stream := self.streams.setdefault(name, named(name))) is not None:
            instance = stream[1]
            if instance is None:
                instance = self.instance(fmt, text)
                if instance is None:
                    self.bad += 1
                    return
            self.places.setdefault((name, instance), []).append(at)

    def define(self, text: bytes, number: int) -> None:
        """An FMT line: one whose Type or Length is no number skipped (a line that does not parse),
        one whose number no binary log could hold refused."""
        parts = [p.strip() for p in text.decode("ascii", "replace").split(",")]
        kind, length = (ascii_int(p) for p in parts[1:3]) if len(parts) >= 3 else (None, None)
        if len(parts) < 6 or kind is None or length is None:
            self.bad += 1
            return
        for column, value, least in (("Type", kind, 0), ("Length", length, 3)):
            if not least <= value <= 255:
                raise InputError(
                    f"the FMT line of {parts[3]!r} gives its {column} as {shown(parts[1 if column == 'Type' else 2])}: "
                    f"not a DataFlash message's (a byte, {least} to 255)",
                    file=self.name,
                    line=number,
                )
        columns = tuple(c for c in parts[5:] if c)
        if parts[3] == "FMT" and columns == ("Type", "Length", "Name", "Format"):
            columns += ("Columns",)  # some text logs leave FMT's last column out (pymavlink DFReader_text)
        self.formats.setdefault(parts[3], Format(kind, parts[3], length, parts[4], columns))

    def instance(self, fmt: Format, text: bytes) -> int | None:
        if "I" not in fmt.columns:
            return 0
        k = fmt.columns.index("I") + 1
        parts = text.split(b",", k + 1)
        if len(parts) <= k:
            return None
        instance = ascii_int(parts[k].strip().decode("ascii", "replace"))
        return instance if instance is not None and instance <= MOST_INSTANCE else None

    def param(self, fmt: Format, text: bytes, number: int) -> None:
        parts = [p.strip() for p in text.decode("ascii", "replace").split(",")]
        if "Name" not in fmt.columns or "Value" not in fmt.columns or len(parts) != len(fmt.columns) + 1:
            self.bad += 1
            return
        key = parts[fmt.columns.index("Name") + 1]
        try:
            value = float(parts[fmt.columns.index("Value") + 1])
        except ValueError:
            self.bad += 1
            return
        self.params[key] = (self.params[key][0], value) if key in self.params else (value, value)
        self.param_at[key] = number


def walk(path: str) -> DataflashIndex:
    """Every line of the text log read once; the wanted messages' lines placed."""
    digest = hashlib.sha256()
    state = _TextWalk(path)
    base, carry, skip, number = 0, b"", False, 0
    with open(path, "rb") as f:
        while block := f.read(CHUNK):
            digest.update(block)
            buf = carry + block if carry else block
            start = 0
            if skip:  # in a "line" longer than any log's: up to its end
                start = buf.find(b"\n") + 1
                if start == 0:
                    carry, base = b"", base + len(buf)
                    continue
                skip = False
            end = max(buf.rfind(b"\n") + 1, start)
            at = base + start
            for text in buf[start:end].split(b"\n")[:-1]:
                number += 1
                state.line(text, at, number)
                at += len(text) + 1
            carry, base = buf[end:], base + end
            if len(carry) > CHUNK:
                state.bad, skip, carry, base = state.bad + 1, True, b"", base + len(carry)
                number += 1
    if carry.strip():
        state.notes.append(
            f"the log ends mid-line (its last {len(carry)} bytes, from byte {base}, with no line end): cut short, "
            "as a log is when power is lost; that line skipped"
        )
    if state.unknown:
        kinds = ", ".join(f"{k} x{n}" for k, n in list(state.unknown.items())[:5])
        more = f" and {len(state.unknown) - 5} more" if len(state.unknown) > 5 else ""
        state.notes.append(f"skipped lines of a message type no FMT line defines ({kinds}{more})")
    if state.bad:
        state.notes.append(f"skipped {state.bad} lines whose fields do not parse")
    found = []
    for (message, instance), places in state.places.items():
        stream = named(message)
        assert stream is not None
        found.append(
            DataflashStream(stream[0], instance, message, state.formats[message], np.asarray(places, dtype=np.int64))
        )
    found.sort(key=lambda s: (s.name, s.instance))
    return DataflashIndex(found, state.params, digest.hexdigest(), state.notes, fields=fields, param_at=state.param_at)


def fields(path: str, src: DataflashStream, names: list[str]) -> dict[str, FloatArray]:
    """The columns ``names`` of ``src``'s lines, parsed a chunk of the log at a time; a line whose
    fields do not parse (or are not as many as its format's columns) is NaN in every column."""
    where = [src.fmt.columns.index(n) + 1 for n in names]
    width = len(src.fmt.columns) + 1
    out = np.full((len(src.places), len(names)), np.nan)
    places: NDArray[np.int64] = src.places
    with open(path, "rb") as f:
        i = 0
        while i < len(places):
            start = int(places[i])
            f.seek(start)
            chunk = f.read(CHUNK)
            first = i
            while i < len(places) and (a := int(places[i]) - start) < len(chunk):
                b = chunk.find(b"\n", a)
                if b < 0 and len(chunk) == CHUNK and i > first:
                    break  # the line goes on past this chunk: read from it
                parts = chunk[a : b if b >= 0 else len(chunk)].split(b",")
                if len(parts) == width:
                    with contextlib.suppress(ValueError):
                        out[i] = [float(parts[k]) for k in where]
                i += 1
    return {n: out[:, k] for k, n in enumerate(names)}


class DftextReader(DataflashReader):
    """io.sources' Reader of ArduPilot DataFlash logs in their text form: walked here, listed and
    read as the binary form is (io.logs.dataflash)."""

    row = logs.DFTEXT

    def walk(self, path: str) -> DataflashIndex:
        return walk(path)


READER = DftextReader()
