"""The one exception family. Each error knows its exit status (docs/reference/exit-status.md)."""

from __future__ import annotations

import contextlib
import re
import signal
import warnings
from collections.abc import Iterator, Mapping
from typing import NamedTuple

#: A fact that words about the command line take: a number or a name.
Fact = str | int | float

#: The words for each code of a Said (a str.format template of its facts), as the edge installs
#: them (use_words). Empty until then.
_WORDS: dict[str, str] = {}


def use_words(table: Mapping[str, str]) -> None:
    """Install the edge's words for each code of a Said: pipeline.hints.WORDS, installed by the
    package's import (tumblecal_cli/__init__), so a Said reads the same wherever it is raised."""
    _WORDS.clear()
    _WORDS.update(table)


class Said(NamedTuple):
    """Words about the command line (a flag, an option's value) that the core says without
    holding them: a stable ``code`` and the ``facts`` the words take. ``str()`` is the code's row
    of the installed table (pipeline.hints) filled with the facts, so an f-string in the core
    reads as the message always read. Without a table installed, the code and its facts. (A
    NamedTuple, not a dataclass: ``import tumblecal_cli`` stays as light as ``--help`` needs.)"""

    code: str
    facts: tuple[tuple[str, Fact], ...] = ()

    def __str__(self) -> str:
        template = _WORDS.get(self.code)
        if template is None:
            return f"[{self.code}{''.join(f' {k}={v!r}' for k, v in self.facts)}]"
        return template.format_map(dict(self.facts))

    def fact(self, name: str) -> Fact:
        """One of the facts, by name."""
        return dict(self.facts)[name]


def said(code: str, **facts: Fact) -> Said:
    """The words of ``code`` with its facts: ``said("pose.short", least=10)``."""
    return Said(code, tuple(facts.items()))


class TumblecalError(Exception):
    """Base of every error tumblecal reports to a user.

    ``str(err)`` is the whole one-line message after ``error: ``; ``hint`` is an optional
    line saying what to do about it. ``more`` are further ``error:`` lines when several things
    are wrong at once (three rejected poses); ``code`` is the stable code of a rejection and
    ``codes`` those of all of them (batch's summary lists them). ``said``: the code and facts of
    the words about the command line that are the message or the hint (given as a Said: a flag
    the core names through pipeline.hints), for a caller that would say them its own way; None
    when there are none.
    """

    exit_code = 2
    code: str | None = None

    def __init__(
        self,
        message: str | Said,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | str | None = None,
        hint: str | Said | None = None,
        more: tuple[str, ...] = (),
        code: str | None = None,
        codes: tuple[str, ...] = (),
    ) -> None:
        self.said = next((w for w in (message, hint) if isinstance(w, Said)), None)
        self.message = str(message)
        self.more = more
        if code is not None:
            self.code = code
        self.codes = codes or ((self.code,) if self.code else ())
        self.file = file
        self.line = line
        self.column = column
        self.hint = None if hint is None else str(hint)
        super().__init__(self.render())

    def render(self) -> str:
        where = []
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.column is not None:
            where.append(f"column {self.column}")
        text = f"{self.file}: {self.message}" if self.file else self.message
        return f"{text} ({', '.join(where)})" if where else text


class InputError(TumblecalError):
    """Usage or input error: bad file, bad option, a units mistake (exit 2)."""

    exit_code = 2


class CaptureRejected(TumblecalError):
    """The data cannot be trusted or cannot determine the parameters (exit 3)."""

    exit_code = 3
    code = "capture.rejected"


class PipeClosed(TumblecalError):
    """Whoever reads stdout went away (``| head``): stop quietly, as a Unix filter does."""

    exit_code = 141


class Interrupted(BaseException):
    """Stopped by SIGTERM (a station's or a scheduler's kill): outputs are cleaned up as for
    an error, and the status is Ctrl-C's. Like KeyboardInterrupt, not an Exception: no handler
    of a unit's or a file's errors takes it for one of theirs; the CLI's boundary reports it."""

    exit_code = 130


#: The signals that stop a command (cli.app's handlers, batch's hold while it publishes, the
#: mask while apply forks its workers): Ctrl-C, a station's or scheduler's kill, a closed terminal.
STOPS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

#: Characters that end a line for a terminal or for str.splitlines, and the rest of C0 and C1 (ESC
#: and CSI start a terminal's control sequences): escaped.
_BREAKS = {c: repr(chr(c))[1:-1] for c in [*range(32), *range(127, 160), 0x2028, 0x2029] if chr(c) != "\t"}


def control_character(text: str) -> str | None:
    """The first control character in ``text`` (C0 or DEL: a line break, a NUL), or None: a
    serial, a station ... holding one would split a summary row or a line for people."""
    return next((ch for ch in text if ord(ch) < 32 or ord(ch) == 127), None)


def one_line(text: str) -> str:
    """``text`` as one line: a file or column name holding a line break (or a NUL) shown escaped."""
    return text.translate(_BREAKS)


#: numpy's floating-point warnings (np.errstate's "warn"): a figure went inf or NaN on the way.
_FLOATING = r"(overflow|invalid value|divide by zero|underflow) encountered"


@contextlib.contextmanager
def numbers_checked() -> Iterator[None]:
    """numpy's floating-point warnings raised as an InputError: a figure that went inf or NaN
    leaves neither a warning on stderr nor a non-finite number with exit 0. Code that means to
    pass NaN through says so with ``np.errstate(invalid="ignore")``, which issues no warning."""
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=_FLOATING, category=RuntimeWarning)
        try:
            yield
        except RuntimeWarning as err:
            if re.match(_FLOATING, str(err)) is None:
                raise
            raise InputError(
                f"a figure came out non-finite ({err}): a number in the inputs or the options is too large "
                "or too small to compute with",
                hint="look for an extreme value in the calibration (tumblecal show CAL), the capture or the options",
            ) from err
