"""A JSON or YAML document read safely: bounded in size, UTF-8, duplicate keys and YAML's
exotic types refused, every problem one line naming the file (calibration, limits and peer files)."""

from __future__ import annotations

import functools
import json
import os
import sys
from typing import TYPE_CHECKING

from tumblecal_cli.errors import InputError

if TYPE_CHECKING:
    import yaml


#: The most a calibration, limits or peer file may hold: they are kilobytes (a calibration with
#: ten thousand poses is 6 MB); a larger one is the wrong file (a capture, a device, /dev/zero).
MAX_BYTES = 16 * 1024 * 1024


def read_bytes(path: str, what: str) -> bytes:
    """The bytes of ``path`` ('-': stdin), at most MAX_BYTES; a missing or unreadable file, or
    one too large to be a {what}, is one error naming it."""
    try:
        if path == "-":  # '-' means stdin wherever a path is taken (README option tables)
            data = sys.stdin.buffer.read(MAX_BYTES + 1)
        else:
            with open(path, "rb") as f:
                data = f.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise InputError(f"no such {what}", file=path) from None
    except IsADirectoryError:
        raise InputError(f"is a directory, not a {what}", file=path) from None
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", file=path) from None
    if len(data) > MAX_BYTES:
        raise InputError(
            f"holds more than {MAX_BYTES // (1024 * 1024)} MB: too large for a {what} (they are kilobytes)",
            file=path,
            hint=f"is this the {what} you meant?",
        )
    return data


def parse_object(raw: bytes, path: str, what: str, *, as_yaml: bool | None = None) -> dict[str, object]:
    """The JSON/YAML object in ``raw`` (YAML when ``path`` ends in .yaml/.yml, or ``as_yaml``)."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"not a {what}: not UTF-8 text", file=path) from None
    if not text.strip():
        raise InputError(f"empty {what}", file=path)
    doc = _parse(text, path, as_yaml=as_yaml)
    if not isinstance(doc, dict):
        raise InputError(f"not a {what}: expected a JSON/YAML object at the top", file=path)
    return doc


def is_yaml(path: str) -> bool:
    return path.lower().endswith((".yaml", ".yml"))


def _parse(text: str, path: str, *, as_yaml: bool | None = None) -> object:
    if as_yaml is None:
        as_yaml = is_yaml(path) or (path == "-" and not text.lstrip().startswith("{"))
    if as_yaml:
        import yaml

        try:
            return yaml.load(text, Loader=_yaml_loader())  # a SafeLoader that also refuses aliases
        except RecursionError:
            raise InputError("not a calibration: its YAML is nested too deeply to read", file=path) from None
        except yaml.YAMLError as err:
            mark = getattr(err, "problem_mark", None)
            problem = getattr(err, "problem", None) or str(err).splitlines()[0]
            raise InputError(
                f"not valid YAML: {problem}",
                file=path,
                line=mark.line + 1 if mark else None,
                column=mark.column + 1 if mark else None,
            ) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        first = text.lstrip("\ufeff").split("\n", 1)[0].strip()
        if first.startswith("serial,status,"):  # batch's summary.csv, given where its calibrations go
            folder = os.path.dirname(path) or "."
            raise InputError(
                "a batch summary (CSV), not a calibration",
                file=path,
                hint=f"give the calibrations: their folder ({folder}) or its *.json files",
            ) from None
        raise InputError(f"not valid JSON: {err.msg}", file=path, line=err.lineno, column=err.colno) from None
    except RecursionError:
        raise InputError("not a calibration: its JSON is nested too deeply to read", file=path) from None
    except ValueError as err:  # an integer of more digits than Python converts (4300)
        raise InputError(f"not valid JSON: {err}", file=path) from None


@functools.cache
def _yaml_loader() -> type[yaml.SafeLoader]:
    """yaml.SafeLoader that refuses aliases (``*name``): a calibration or limits file has no use
    for them, and a tree of aliases expands exponentially (a few hundred bytes can become GB)."""
    import yaml

    class NoAliases(yaml.SafeLoader):
        def compose_node(self, parent: yaml.Node | None, index: int) -> yaml.Node | None:
            if self.check_event(yaml.events.AliasEvent):
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]
                raise yaml.composer.ComposerError(
                    None, None, "an alias (*name): tumblecal's files are read without them", mark
                )
            return super().compose_node(parent, index)

    return NoAliases


def read_object(path: str, what: str) -> dict[str, object]:
    """The JSON/YAML object in ``path`` ('-': stdin)."""
    return parse_object(read_bytes(path, what), path, what)
