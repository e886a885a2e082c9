"""The Typer application and the one error boundary: every error becomes its exit status here.

numpy, pyarrow and the pipeline are imported inside the commands, so ``tumblecal --help`` and
``--version`` pay only for Typer.
"""

from __future__ import annotations

import contextlib
import copy
import errno
import functools
import os
import re
import sys
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Annotated

import typer
from typer.core import TyperCommand, TyperOption

from tumblecal_cli.cli.flags import EXIT_CODES
from tumblecal_cli.errors import STOPS, Interrupted, PipeClosed, TumblecalError, numbers_checked, one_line
from tumblecal_cli.version import __version__

if TYPE_CHECKING:
    from types import FrameType

    from typer._click import Command as ClickCommand  # the click that Typer bundles (and builds on)
    from typer._click import Context, HelpFormatter, Parameter
    from typer.models import CommandInfo

# The solvers' matrices are 3x3 to 12x12: BLAS threads only cost start-up and spin (see core.model.apply).
# Set before numpy is first imported (lazily, inside the commands); a user's own setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# numpy asks the kernel for transparent huge pages for every large array. Where those are slow
# to fault in (on the virtual machines this was measured on: 960 MB written into fresh arrays in
# 1.84 s with them, 0.36 s without; segment of 20M rows 4.6-4.8 s vs 3.4-4.3 s) a command that
# fills arrays once and streams pays for it and gains nothing. The CLI only: the Python API
# leaves a user's numpy as it is; a user's own setting wins.
os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

app = typer.Typer(
    name="tumblecal",
    help="Calibrate 3-axis sensors from static tumble poses, and correct captures with the result.",
    epilog=EXIT_CODES,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)

_state = {"debug": False}


#: Help longer than this many lines of options is cut to the options a user needs first (those in
#: no panel, and the panels in FIRST_PANELS), described; each other panel lists its options' names.
LONG_HELP = 60

#: Panels described in full in a short help: a command's own options (batch's).
FIRST_PANELS = ("Arguments", "Options", "Batch")


#: What an internal error says to do: --debug is the tool's option, before the command.
DEBUG_HINT = "run it again as tumblecal --debug COMMAND ... for the traceback"


def _help_all(ctx: Context, param: object, value: bool) -> None:
    if value and not ctx.resilient_parsing:
        ctx.meta["help_all"] = True
        typer.echo(ctx.get_help(), color=ctx.color)
        ctx.exit()


class Command(TyperCommand):
    """Plain help, with the options grouped under the ``rich_help_panel`` each one names. A long
    one describes the options a user needs first and names the others by panel; ``--help-all``
    describes every option."""

    first_panels: tuple[str, ...] = FIRST_PANELS  # described in a short help

    def format_help_text(self, ctx: Context, formatter: HelpFormatter) -> None:
        """The first line, then the examples (a ``\\b`` paragraph of ``tumblecal`` lines), then the rest."""
        import inspect

        paragraphs = inspect.cleandoc(self.help or "").partition("\f")[0].split("\n\n")
        examples = [p for p in paragraphs[1:] if p.startswith("\b") and "tumblecal " in p]
        if examples:
            rest = [p for p in paragraphs[1:] if p is not examples[0]]
            text = "\n\n".join([paragraphs[0], examples[0], *rest])
            formatter.write_paragraph()
            with formatter.indentation():
                formatter.write_text(text)
            return
        super().format_help_text(ctx, formatter)

    def get_params(self, ctx: Context) -> list[Parameter]:
        params = super().get_params(ctx)
        if not any("--help-all" in getattr(p, "opts", ()) for p in params):
            params.append(_HELP_ALL)
        return params

    def format_options(self, ctx: Context, formatter: HelpFormatter) -> None:
        sections: dict[str, list[tuple[str, str]]] = {}
        names: dict[str, list[str]] = {}
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record is not None:
                kind = "Arguments" if param.param_type_name == "argument" else "Options"
                panel = getattr(param, "rich_help_panel", None) or kind
                sections.setdefault(panel, []).append(record)
                names.setdefault(panel, []).append(next((w for w in record[0].split() if w.startswith("--")), ""))
        ordered = sorted(sections.items(), key=lambda kv: kv[0] != "Arguments")
        lines = sum(len(r[1]) // max(formatter.width - 34, 20) + 1 for _, rs in ordered for r in rs)
        short = lines > LONG_HELP and not ctx.meta.get("help_all")
        for title, records in ordered:
            if short and title not in self.first_panels:
                continue
            with formatter.section(title):
                formatter.write_dl(records)
        if short:
            _name_panels(formatter, [(t, names[t]) for t, _ in ordered if t not in self.first_panels])


def _name_panels(formatter: HelpFormatter, panels: list[tuple[str, list[str]]]) -> None:
    """Each panel of a short help as its title and its options' names, wrapped between names."""
    import textwrap

    with formatter.section("More options (--help-all describes them)"):
        for title, names in panels:
            formatter.write_text(f"{title}:")
            text = textwrap.fill(
                " ".join(names),
                formatter.width - formatter.current_indent,
                initial_indent="  ",
                subsequent_indent="  ",
                break_on_hyphens=False,
                break_long_words=False,
            )
            formatter.write(textwrap.indent(text, " " * formatter.current_indent) + "\n")


_HELP_ALL = TyperOption(
    param_decls=["--help-all"],
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_help_all,
    help="Show every option, described, and exit.",
)


class ManyValuesCommand(Command):
    """Lets ``--poses a.csv b.csv c.csv`` take every file after one flag.

    Click options have a fixed arity, so before parsing, each value that follows ``--poses``
    (up to the next option) becomes its own ``--poses=VALUE``. ``-`` (stdin) is a value, and so
    is a labelled item whose label starts with '-' (``-x=xn.csv``).
    """

    many = ("--poses", "-p")

    def parse_args(self, ctx: Context, args: list[str]) -> list[str]:
        out: list[str] = []
        flag: str | None = None
        for arg in args:
            name = arg.split("=", 1)[0]
            if arg == "--":
                flag = None
            elif name in self.many:
                flag = name
                if "=" in arg:
                    out.append(arg)
                    continue
                if arg == name:
                    out.append(arg)
                    continue
            elif flag and (arg == "-" or not arg.startswith("-") or _is_labelled(arg)):
                if out[-1] == flag:  # the flag's own value: keep the flag, give it the value with '='
                    out.pop()
                out.append(f"--poses={arg}")  # '=' so that '-x=xn.csv' is a value, not an option
                continue
            else:
                flag = None
            out.append(arg)
        return super().parse_args(ctx, out)


class LabelledItemsCommand(Command):
    """Lets positional items labelled with a '-' face (``-z=down.csv``) through: they are moved
    after a ``--``, where Click takes them as arguments, not options."""

    def parse_args(self, ctx: Context, args: list[str]) -> list[str]:
        if "--" in args:
            return super().parse_args(ctx, args)
        labelled = [a for a in args if _is_labelled(a)]
        rest = [a for a in args if not _is_labelled(a)]
        return super().parse_args(ctx, [*rest, "--", *labelled] if labelled else rest)


def _is_labelled(arg: str) -> bool:
    """Whether ``arg`` looks like a pose item ``LABEL=FILE`` whose label starts with '-'
    (``-x=xn.csv``, ``-0.5,0,0.87=a.csv``), not an option. (A pattern, not core.parse_label:
    parsing the command line must not import numpy.) The label is validated later."""
    label, sep, _ = arg.partition("=")
    number = r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"
    return bool(sep) and re.fullmatch(rf"[-+][xyz]|{number},{number},{number}", label.lower()) is not None


def _version(value: bool) -> None:
    if value:
        typer.echo(f"tumblecal {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the traceback of an error.")] = False,
) -> None:
    _state["debug"] = debug


@contextlib.contextmanager
def _term_as_interrupt() -> Iterator[None]:
    """Ctrl-C, SIGTERM (a scheduler's or a station's kill) and SIGHUP stop a command alike:
    partial outputs removed, a batch's summary written and its worker processes shut down;
    exit 130."""
    import signal

    def interrupt(signum: int, frame: FrameType | None) -> None:
        raise Interrupted("interrupted" if signum == signal.SIGINT else f"interrupted ({signal.Signals(signum).name})")

    # Ctrl-C as well (Typer turns a KeyboardInterrupt into a silent status 130), and a closed
    # terminal's SIGHUP; a signal the caller ignores (nohup, a background job) stays ignored
    caught = [s for s in STOPS if signal.getsignal(s) != signal.SIG_IGN]
    try:
        previous = [(s, signal.signal(s, interrupt)) for s in caught]
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        for signum, handler in previous:
            signal.signal(signum, handler)


@functools.cache
def _command(name: str | None = None) -> ClickCommand:
    """The click command Typer builds from the command functions' signatures: built once per
    process (it costs 20-30 ms; a batch's in-process units and the tests call main many times).
    With ``name``, a command's name, the group holds that command alone (2 ms): what a script's
    ``tumblecal apply ...`` needs, parsed and reported exactly as by the whole group."""
    if name is not None:
        one = [c for c in app.registered_commands if _name(c) == name]
        group = [g for g in app.registered_groups if g.name == name]  # (``records``: its commands alone)
        if one or group:
            alone = copy.copy(app)
            alone.registered_commands, alone.registered_groups = one, group
            return typer.main.get_command(alone)
    return typer.main.get_command(app)


def _name(info: CommandInfo) -> str | None:
    callback = info.callback
    return info.name or (typer.main.get_command_name(callback.__name__) if callback is not None else None)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit status. Every error is reported here and only here: one
    line on stderr, and with --json an error object on stdout (:func:`json_error`)."""
    from tumblecal_cli.cli import render

    args = sys.argv[1:] if argv is None else list(argv)
    render.json_printed(reset=True)
    try:
        with _term_as_interrupt(), numbers_checked():  # a kill cleans up as Ctrl-C; numpy's warnings as ours
            named = args[0] if args and not args[0].startswith("-") else None
            result = _command(named).main(args=argv, prog_name="tumblecal", standalone_mode=False)
        sys.stdout.flush()  # a reader that stopped early (`| head`) is found here, not at exit
    except (PipeClosed, BrokenPipeError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return PipeClosed.exit_code
    except TumblecalError as err:
        if _state["debug"]:
            raise
        report(str(err), err.hint, err.more)
        json_error(args, err.exit_code, _fields(err.message, err.hint, err.file, err.line, err.column, err.more))
        return err.exit_code
    except typer.Exit as err:
        return err.exit_code
    except typer.TyperException as err:  # the parser's usage errors: one line, like ours
        if type(err).__name__ == "NoArgsIsHelpError":  # bare `tumblecal`: the help, on stderr
            getattr(err, "show", print)()
            return 2
        ctx = getattr(err, "ctx", None)
        command = ctx.command_path if ctx is not None else "tumblecal"
        report(err.format_message(), f"see '{command} --help'")
        json_error(args, 2, _fields(err.format_message(), f"see '{command} --help'"))
        return 2
    except (typer.Abort, KeyboardInterrupt):
        report("interrupted", None)
        return 130
    except Interrupted as err:  # SIGTERM (_term_as_interrupt)
        report(str(err), None)
        return Interrupted.exit_code
    except OSError as err:  # the system refused (a full disk, stdout on /dev/full): not a bug
        if _state["debug"]:
            raise
        # a write with no file named is a standard stream's (every file goes through io.outputs)
        text, name = f"{err.strerror or err}", err.filename
        if name is None and err.errno in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT):
            text, name = f"cannot write: {text}", "<stdout>"
        report(f"{name}: {text}" if name else text, None)
        json_error(args, 2, _fields(text, None, name))
        return 2
    except Exception as err:  # a bug: one line unless --debug
        if _state["debug"]:
            raise
        said = f"internal error: {type(err).__name__}: {err}"
        report(said, DEBUG_HINT)
        json_error(args, 2, _fields(said, DEBUG_HINT))
        return 2
    finally:
        _state["debug"] = False
    return result if isinstance(result, int) else 0


def json_error(args: list[str], status: int, error: Mapping[str, object]) -> None:
    """With --json (on a command that takes it), an error that ends the command prints
    ``{"status": "error", "exit_status": 2, "error": {...}}`` on stdout, unless the command
    printed its own document first (a report of the files it could read, a rejected solve's
    summary): stdout holds one JSON document, whole."""
    from tumblecal_cli.cli import render

    if status not in (2, 3) or render.json_printed() or not _wants_json(args):
        return
    with contextlib.suppress(PipeClosed, OSError):  # a reader gone: the status says it all
        render.error_json(status, error)


def _wants_json(args: list[str]) -> bool:
    """Whether ``args`` give --json to a command that has that option (before any ``--``)."""
    name = next((a for a in args if not a.startswith("-")), None)
    command = getattr(_command(), "commands", {}).get(name) if name else None
    if command is None or not any("--json" in getattr(p, "opts", ()) for p in command.params):
        return False
    rest = args[args.index(str(name)) + 1 :]
    return "--json" in (rest[: rest.index("--")] if "--" in rest else rest)


def _fields(
    message: str,
    hint: str | None,
    file: str | None = None,
    line: int | None = None,
    column: int | str | None = None,
    more: tuple[str, ...] = (),
) -> dict[str, object]:
    return {"file": file, "line": line, "column": column, "message": message, "hint": hint, "more": list(more)}


def report(message: str, hint: str | None, more: tuple[str, ...] = ()) -> None:
    """Each error one line on stderr (a file or column name holding a line break is shown escaped);
    a stderr that cannot be written (a hung-up terminal) takes nothing, and the status stands."""
    with contextlib.suppress(OSError):
        for line in (message, *more):
            print(f"error: {one_line(line)}", file=sys.stderr)
        if hint:
            print(f"hint: {one_line(hint)}", file=sys.stderr)


def _closed_streams() -> None:
    """A standard stream the caller closed (``>&-``, ``2>&-``, ``<&-``) is /dev/null instead, as
    Python's own print treats it: the run goes on, no file it opens takes that number (an output
    written as fd 1 would get whatever is printed), and no message goes where data goes."""
    for fd, name, mode in ((0, "stdin", "r"), (1, "stdout", "w"), (2, "stderr", "w")):
        try:
            os.fstat(fd)
            continue
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)  # the lowest free number: this one, the lower ones open
        if null != fd:
            os.dup2(null, fd)
            os.close(null)
        stream = open(fd, mode, encoding="utf-8", closefd=False)  # noqa: SIM115
        stream.closed_by_caller = True  # type: ignore[attr-defined]  # data for it is an error (io.outputs)
        setattr(sys, name, stream)


def main_exit() -> None:
    """Console-script entry point: the status, without the interpreter's teardown.

    Every file is written (atomically) and every pool shut down before main() returns; what
    is left is the interpreter's teardown, where a native library's thread (pyarrow's, seen
    about once in 500 runs) could abort the process and turn a documented status into 134."""
    _closed_streams()
    try:
        status = main()
    except (KeyboardInterrupt, Interrupted):  # a second stop while the first was being told
        status = 130
    except Exception as err:  # only --debug lets one through: its traceback, and the status all the same
        import traceback

        with contextlib.suppress(OSError):
            traceback.print_exc()
        status = err.exit_code if isinstance(err, TumblecalError) else 2
    import signal

    for stop in STOPS:  # the work is done: no traceback in the exit
        signal.signal(stop, signal.SIG_IGN)
    if "multiprocessing" in sys.modules:  # batch --jobs: the exit work of its pool's module (the
        from multiprocessing import util  # forkserver's folder in $TMPDIR, left behind otherwise)

        util._exit_function()  # type: ignore[attr-defined]
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: main() has said so already
            stream.flush()
    os._exit(status)
