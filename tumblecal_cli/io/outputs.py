"""Outputs: atomic writes, '-' for stdout, and the rule that no command writes onto an input."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import shlex
import shutil
import stat
import sys
import time
from collections.abc import Iterable, Iterator
from typing import IO

from tumblecal_cli.errors import InputError, PipeClosed

#: What a failed write of an output says (disk full, file too large, quota exceeded).
WRITE_ERRORS = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


#: A text cell starting with one of these is a formula to a spreadsheet (CSV injection): OWASP's
#: = + - @, tab and carriage return, and their full-width forms (an input method, or a
#: spreadsheet's own clean-up, can fold ＝ into =: a ' costs nothing on cells no station writes).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r", "\uff1d", "\uff0b", "\uff0d", "\uff20")
#: A number as tumblecal writes one (-0.01, 1e-05, -inf): a spreadsheet's number, not a formula.
_NUMBER = re.compile(r"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|inf|nan)")
#: tumblecal's own words that start with a sign: a face (+z, -x). Written as they are: no input's
#: text, so nothing to inject, and a script reading an index compares them as they are printed.
_OWN = re.compile(r"[+-][xyz]")


#: The most a run keeps in $TMPDIR to read again (a log from stdin or a pipe, unless --max-spool
#: says otherwise; a long pose file's readings); less when $TMPDIR has less room than that: its
#: free space less a margin, SPOOL_MARGIN or a tenth of the free space, whichever is less (the
#: disk is not filled up).
MAX_SPOOL = 4 << 30
SPOOL_MARGIN = 256 << 20


def spool_room(folder: str) -> int:
    """MAX_SPOOL, or the room in ``folder`` less a margin when that is less."""
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return MAX_SPOOL
    return max(0, min(MAX_SPOOL, free - min(SPOOL_MARGIN, free // 10)))


def spreadsheet_safe(cell: str) -> str:
    """A CSV cell a spreadsheet shows as text: one that would start a formula gets a leading
    ``'`` (OWASP's advice); numbers, negative ones included, are left as they are. A cell that
    already starts with ``'`` before such a start gets one more, so that :func:`unsafe` gives
    back exactly the cell it was. A face (+z, -x) is tumblecal's own word, written as it is."""
    if not cell.lstrip("'").startswith(FORMULA_STARTS) or _NUMBER.fullmatch(cell) or _OWN.fullmatch(cell):
        return cell
    return "'" + cell


def unsafe(cell: str) -> str:
    """The cell :func:`spreadsheet_safe` was given."""
    return cell[1:] if cell.startswith("'") and cell.lstrip("'").startswith(FORMULA_STARTS) else cell


def check_not_input(output: str, inputs: Iterable[str], flag: str = "-o") -> None:
    """Refuse an output path that names one of the inputs (same file, any spelling)."""
    if output == "-" or not os.path.exists(output):
        return
    for path in inputs:
        # `... -o c.csv < c.csv`: the input on stdin is that very file
        same = _is_stdin(output) if path == "-" else os.path.exists(path) and os.path.samefile(output, path)
        if same:
            what = "standard input" if path == "-" else path
            raise InputError(
                f"{flag} would overwrite the input {what}", file=output, hint="write the output to a new file"
            )


def _is_stdin(path: str) -> bool:
    try:
        there, here = os.fstat(sys.stdin.fileno()), os.stat(path)
    except (OSError, ValueError, AttributeError):  # no stdin, or one without a file descriptor
        return False
    return (there.st_dev, there.st_ino) == (here.st_dev, here.st_ino)


def _named(path: str, flag: str = "-o") -> None:
    """An output named nothing, or a folder by its trailing '/': the rename at the end would
    fail naming only its temporary file."""
    if not path:
        raise InputError(f"{flag} names no file (an empty name)", hint=f"give a file name, or {flag} - for stdout")
    if path.endswith(("/", os.sep)):
        raise InputError(f"names a folder (it ends with '/'): {flag} takes a file name", file=path)


def _make_it(folder: str) -> str:
    return f"make it first: mkdir -p {shlex.quote(folder)}"


def check_writable(output: str, flag: str = "-o") -> None:
    """Refuse an output that cannot be written, before any work: a usage error (exit 2) comes
    before a rejection (3) or a failed limit (1), and a folder is never replaced by a file."""
    if output == "-":
        return
    _named(output, flag)
    if os.path.isdir(output):
        raise InputError(f"is a folder: {flag} takes a file name", file=output)
    folder = os.path.dirname(os.path.abspath(output))
    if not os.path.isdir(folder):
        raise InputError("the output folder does not exist", file=output, hint=_make_it(folder))


@contextlib.contextmanager
def atomic_output(path: str, *, exclusive: bool = False) -> Iterator[IO[bytes]]:
    """A binary stream for ``path`` ('-': stdout). A file appears (or is replaced) only when
    the block finishes without an error; on an error the old file is left as it was.

    A path that is not a regular file (``/dev/null``, ``/dev/stdout``, a named pipe) is written
    into as it is: replacing it would put a file where a device was. A symbolic link to a file
    keeps its link: the file it points to is what is replaced.

    ``exclusive``: nothing is ever replaced. A name that is taken (by anything: a file, a link, a
    device), when the block starts or by the time it ends, is an error naming it, and is left as
    it is: the check and the publish are one step (a hard link, which fails on a taken name), so
    two runs writing one name cannot both succeed."""
    if exclusive and path != "-":
        _named(path, "the output")
        if os.path.lexists(path):
            raise _taken(path)
    stream = _stream_for(path) if not exclusive or path == "-" else None
    if stream is not None:
        with stream as out:
            yield out
        return
    _named(path, "the output")
    path = _target(path) if os.path.islink(path) and not exclusive else path
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError("the output folder does not exist", file=path, hint=_make_it(folder))
    if folder not in _SWEPT:  # once per folder and process: a batch writes thousands of files into one
        _SWEPT.add(folder)
        remove_stale(folder)
    # named before it is made, inside the try that removes it: a stop (Ctrl-C, SIGTERM) that lands
    # as it is made cannot leave it behind (the PID in the name: no other running process's)
    name = os.path.basename(path).encode()[:SHORTEST].decode(errors="ignore")  # room for the rest: 255 bytes
    base, tmp = os.path.join(folder, f".{name}.{os.getpid()}-"), ""
    try:
        fd = -1
        while fd < 0:
            tmp = f"{base}{secrets.token_hex(4)}.tmp"
            try:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)  # less the umask
            except FileExistsError:
                continue
            except OSError as err:
                tmp = ""  # not made
                raise InputError(f"cannot write: {err.strerror}", file=path) from None
        try:
            with os.fdopen(fd, "wb") as f:
                yield f
        except OSError as err:  # a write that failed has no file name of its own: give the output's
            if err.errno not in WRITE_ERRORS:
                raise
            raise InputError(f"cannot write: {err.strerror}", file=path) from None
        if exclusive:
            _publish_new(tmp, path)
        else:
            _publish(tmp, path)
    except BaseException:
        if tmp:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise


def _target(link: str) -> str:
    """The file a symbolic link names (it is what is replaced: the link stays); a link that
    loops names none, and is an error rather than replaced by a file."""
    try:
        return os.path.realpath(link, strict=True)
    except FileNotFoundError:  # a dangling link: the file it names is made
        return os.path.realpath(link)
    except OSError as err:
        raise InputError(f"cannot write: {err.strerror} (a symbolic link that loops?)", file=link) from None


def _stream_for(path: str) -> contextlib.AbstractContextManager[IO[bytes]] | None:
    """What ``path`` is written into as it is (stdout, another open stream, a device or a pipe),
    or None for a file to replace."""
    if path == "-" or path in ("/dev/stdout", "/dev/fd/1", "/proc/self/fd/1"):  # the same stream
        if getattr(sys.stdout, "closed_by_caller", False):  # `>&-`: the data would go nowhere
            raise InputError("is closed: the output has nowhere to go", file="<stdout>", hint="give -o FILE")
        return _stdout()
    if path in ("/dev/stderr", "/dev/fd/2", "/proc/self/fd/2") and getattr(sys.stderr, "closed_by_caller", False):
        raise InputError("is closed: the output has nowhere to go", file="<stderr>", hint="give -o FILE")
    if re.fullmatch(r"/dev/(?:stderr|fd/\d+)|/proc/self/fd/\d+", path):  # another open stream: append
        return _opened(path, "ab")  # ("wb" would truncate a file behind it)
    try:
        mode = os.stat(path).st_mode
    except OSError:  # not there (or a dangling link): a new file
        return None
    if stat.S_ISDIR(mode):
        raise InputError("is a folder: an output is a file name", file=path)
    if stat.S_ISFIFO(mode):
        return _fifo(path)
    return None if stat.S_ISREG(mode) else _opened(path, "wb")


#: How long an output that is a named pipe waits for a reader (open(2) would block for ever, and
#: a station script could not tell a hung run from a slow one).
FIFO_WAIT = 30.0


@contextlib.contextmanager
def _fifo(path: str) -> Iterator[IO[bytes]]:
    """A named pipe opened for writing once a reader has it open, waiting at most FIFO_WAIT
    seconds (a non-blocking open fails with ENXIO until then); then written as a blocking stream."""
    deadline = time.monotonic() + FIFO_WAIT
    while True:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC)
            break
        except OSError as err:
            if err.errno != errno.ENXIO:
                raise InputError(f"cannot write: {err.strerror}", file=path) from None
            if time.monotonic() >= deadline:
                raise InputError(
                    f"a named pipe with no reader after {FIFO_WAIT:g} s: nothing would take the output",
                    file=path,
                    hint="start its reader first (or write to a file)",
                ) from None
            time.sleep(0.05)
    os.set_blocking(fd, True)
    with _stream_errors(path), os.fdopen(fd, "wb") as stream:
        yield stream


@contextlib.contextmanager
def _stdout() -> Iterator[IO[bytes]]:
    with _stream_errors("<stdout>"):
        yield sys.stdout.buffer
        sys.stdout.buffer.flush()


@contextlib.contextmanager
def _opened(path: str, mode: str) -> Iterator[IO[bytes]]:
    with _stream_errors(path), open(path, mode) as stream:
        yield stream


def _publish(tmp: str, path: str) -> None:
    """The temporary file ``tmp``, whole, renamed over ``path`` with the old file's permissions
    (a new one keeps its own: 0666 less the umask, as it was made)."""
    if os.path.exists(path):
        os.chmod(tmp, os.stat(path).st_mode & 0o777)
    try:
        os.replace(tmp, path)
    except OSError as err:  # the name's, not the temporary file's
        raise InputError(f"cannot write: {err.strerror}", file=path) from None


def _publish_new(tmp: str, path: str) -> None:
    """The temporary file ``tmp``, whole, under the name ``path`` only if no file has it: a hard
    link fails on a taken name (the check and the publish in one step), then the temporary name
    goes. Where a file system has no hard links, an exclusive create of ``path`` claims the name
    first and the temporary file is renamed over that claim."""
    try:
        os.link(tmp, path, follow_symlinks=False)
    except FileExistsError:
        raise _taken(path) from None
    except OSError as err:
        if err.errno not in _NO_LINKS:
            raise InputError(f"cannot write: {err.strerror}", file=path) from None
        _claim(path)
        try:
            _publish(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(path)  # the empty claim: this process's own
            raise
        return
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)


def _claim(path: str) -> None:
    """``path`` made, empty, by this process alone (it was free): or an error naming it."""
    try:
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666))
    except FileExistsError:
        raise _taken(path) from None
    except OSError as err:
        raise InputError(f"cannot write: {err.strerror}", file=path) from None


def _taken(path: str) -> InputError:
    return InputError(
        "already exists: never replaced (another run may be writing the same name)",
        file=path,
        hint="write into a new or empty folder",
    )


#: What os.link says on a file system without hard links (FAT, some network and FUSE mounts).
_NO_LINKS = frozenset({errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.ENOSYS, errno.EMLINK})

#: The bytes of an output's name its temporary file's name keeps (a name of 255 bytes is allowed,
#: and the temporary file's adds its own 20).
SHORTEST = 100

#: Folders whose stale temporary files this process has already removed.
_SWEPT: set[str] = set()
#: The temporary file of an atomic output: ``.NAME.PID-XXXXXXXX.tmp``.
TEMPORARY = re.compile(r"\..+\.(\d+)-[A-Za-z0-9_]{8}\.tmp")


#: A temporary file or staging folder this much older than now is a dead writer's whatever its pid
#: says (a writer in another PID namespace, a container's, whose pid is a live process here).
STALE_AGE = 24 * 3600.0
#: An entry last written this long before its pid's process started is not that process's (the
#: margin: a network file system's clock, which stamps the time, may run behind this machine's).
SKEW = 600.0


def remove_stale(folder: str, pattern: re.Pattern[str] = TEMPORARY) -> list[str]:
    """Remove what a killed tumblecal left in ``folder``: only entries whose whole name matches
    ``pattern`` (tumblecal's own naming, its first group the writer's pid: temporary files of
    atomic outputs by default, a batch's or a segment run's staging), and of those only a dead
    writer's: its process gone on this machine, or the entry older than the process that now has
    its pid (a pid taken again, or another PID namespace's), or not written for STALE_AGE. Never
    anybody else's, never a running writer's. The names removed."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.listdir(folder):
            found = pattern.fullmatch(entry)
            if found is None or int(found.group(1)) == os.getpid():
                continue
            path = os.path.join(folder, entry)
            with contextlib.suppress(OSError):
                if not _dead_writer(int(found.group(1)), os.lstat(path).st_mtime):
                    continue
                if os.path.isdir(path) and not os.path.islink(path):
                    shutil.rmtree(path)
                else:
                    os.unlink(path)
                removed.append(entry)
    return removed


def _dead_writer(pid: int, written: float) -> bool:
    """Whether the writer whose pid an entry carries, last written at ``written`` (its mtime, which
    is no earlier than when it was made), is gone: no such process, one started after the entry
    was last written (so not its writer), or an entry left unwritten for STALE_AGE."""
    if not alive(pid) or time.time() - written > STALE_AGE:
        return True
    started = started_at(pid)
    return started is not None and written < started - SKEW


def started_at(pid: int) -> float | None:
    """When process ``pid`` started (seconds since the epoch), from /proc; None where unknown."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rpartition(b")")[2].split()  # after the command's name, which may hold spaces
        with open("/proc/stat", "rb") as f:
            boot = next(int(ln.split()[1]) for ln in f if ln.startswith(b"btime "))
        return boot + int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22 of stat(5): start time in ticks
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs on this machine (one of another user's counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):  # another user's process, or no such pid at all
        return True
    return True


@contextlib.contextmanager
def _stream_errors(name: str) -> Iterator[None]:
    """A stream's write errors as tumblecal's: a closed reader, a full disk naming ``name``."""
    try:
        yield
    except BrokenPipeError:
        raise PipeClosed(f"{name} was closed") from None
    except OSError as err:
        if err.errno not in WRITE_ERRORS:
            raise
        raise InputError(f"cannot write: {err.strerror}", file=name) from None
