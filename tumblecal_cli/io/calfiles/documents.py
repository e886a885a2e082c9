"""A JSON or YAML document read safely: bounded in size, UTF-8, duplicate keys and YAML's
exotic types refused, every problem one line naming the file (calibration, limits and peer files)."""

from __future__ import annotations

import functools
import json
import os
import re
import sys
from collections.abc import Callable
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
        if path == "-":  # '-' means stdin wherever a path is taken (docs/ option tables)
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
            return yaml.load(text, Loader=_yaml_loader())  # a SafeLoader of JSON's values only (_yaml_loader)
        except _Refused as err:
            raise InputError(err.message, file=path, line=err.line, column=err.column) from None
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
        doc = json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_not_a_json_number)
        _no_lone_surrogates(doc)
        return doc
    except _Refused as err:
        raise InputError(err.message, file=path) from None
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


class _Refused(Exception):
    """A document that parses but that tumblecal does not read (a key given twice, a value JSON
    has no form for, half a surrogate pair), where it is when known."""

    def __init__(self, message: str, line: int | None = None, column: int | None = None) -> None:
        super().__init__(message)
        self.message, self.line, self.column = message, line, column


def _field(where: str) -> str:
    return f"field {where!r}" if where else "the document"


def _unique_keys(pairs: list[tuple[str, object]]) -> dict[str, object]:
    """A JSON object, refused when it names a key twice (json.loads keeps the last: which of the
    two did the writer mean?)."""
    doc = dict(pairs)
    if len(doc) < len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _Refused(f"key {key!r} is given twice in one object: which one is meant?")
            seen.add(key)
    return doc


def _not_a_json_number(name: str) -> object:
    """NaN, Infinity or -Infinity, which Python's json reads but JSON has no form for: refused, as
    a file holding one could be read here but written by no export and read by no other tool."""
    raise _Refused(f"every number must be finite ({name}: JSON has no form for it): write a number or leave it out")


#: Half a UTF-16 surrogate pair: JSON's "\udc00" and YAML's "\udc00" escapes decode to one, which
#: no UTF-8 output (a terminal, an export, the calibration written again) can encode.
_SURROGATE = re.compile("[\ud800-\udfff]")


def _surrogate_message(text: str, what: str) -> str | None:
    """What is wrong with ``text``, the value ``what`` ("field 'unit.serial'"), if it holds half a pair."""
    found = _SURROGATE.search(text)
    if found is None:
        return None
    return (
        f"{what} holds {ascii(found.group())[1:-1]}, half of a UTF-16 surrogate pair: not a character"
        " (write the character itself, in UTF-8)"
    )


def _no_lone_surrogates(doc: object) -> None:
    """Refuse a lone surrogate anywhere in a JSON document (a valid pair of escapes decodes to
    its character: what is left is half of one), naming its field."""
    stack: list[tuple[object, str]] = [(doc, "")]
    while stack:
        value, where = stack.pop()
        if isinstance(value, dict):
            for key, item in value.items():
                if problem := _surrogate_message(key, f"a key of {_field(where)}"):
                    raise _Refused(problem)
                stack.append((item, f"{where}.{key}" if where else key))
        elif isinstance(value, list):
            stack.extend((item, f"{where}[{k}]") for k, item in enumerate(value))
        elif isinstance(value, str) and (problem := _surrogate_message(value, _field(where))):
            raise _Refused(problem)


_TAG = "tag:yaml.org,2002:"
#: The YAML tags of JSON's values: what a calibration, limits or peer file holds.
_JSON_TAGS = {_TAG + t for t in ("str", "int", "float", "bool", "null", "seq", "map")}
#: What the refused tags are, for the message.
_KINDS = {
    "binary": "binary data (!!binary)",
    "set": "a set (!!set)",
    "timestamp": "a timestamp (!!timestamp)",
    "omap": "an ordered map (!!omap)",
    "pairs": "a list of pairs (!!pairs)",
    "merge": "a merge key (<<)",
}

#: YAML 1.1's implicit types narrowed to those a reader sees at a glance: no timestamps (a date is
#: its text), no sexagesimal numbers (``1:00`` is text, not 60), no octal with a leading zero (a
#: serial ``0042`` is text, not 34), no yes/no/on/off booleans (a serial ``NO`` stays NO), no ``=``.
#: Only narrowed, never widened: what YAML 1.1 writers (yaml.safe_dump) leave unquoted as text
#: is still text here.
_RESOLVERS = (
    ("bool", r"^(?:true|True|TRUE|false|False|FALSE)$", "tTfF"),
    ("int", r"^(?:[-+]?0b[0-1_]+|[-+]?0|[-+]?[1-9][0-9_]*|[-+]?0x[0-9a-fA-F_]+)$", "-+0123456789"),
    (
        "float",
        r"^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+][0-9]+)?|\.[0-9][0-9_]*(?:[eE][-+][0-9]+)?"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$",
        "-+0123456789.",
    ),
    ("null", r"^(?:~|null|Null|NULL|)$", ["~", "n", "N", ""]),
    ("merge", r"^(?:<<)$", "<"),
)


def _place(node: yaml.Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


def _refuse(node: yaml.Node, where: str, *, key: bool = False) -> None:
    """A node whose tag is not one of JSON's values, a scalar holding half a surrogate pair, or
    a number Python does not read as it looks (base 60, more digits than 4300)."""
    what = f"a key of {_field(where)}" if key else _field(where)
    if node.tag not in _JSON_TAGS:
        short = node.tag.removeprefix(_TAG)
        kind = _KINDS.get(short) or f"of the tag {'!!' + short if short != node.tag else short}"
        raise _Refused(
            f"{what} is {kind}: tumblecal reads JSON's values only (text, numbers, true/false, null, lists, objects)",
            *_place(node),
        )
    if not isinstance(node.value, str):
        return
    if problem := _surrogate_message(node.value, what):
        raise _Refused(problem, *_place(node))
    if node.tag in (_TAG + "int", _TAG + "float") and ":" in node.value:  # !!int 1:00 (text without the tag)
        raise _Refused(f"{what} is a base-60 number ({node.value}): write it in decimal", *_place(node))
    if node.tag == _TAG + "float" and re.fullmatch(r"[-+]?\.(?:inf|Inf|INF|nan|NaN|NAN)", node.value):
        raise _Refused(f"{what} must be a finite number ({node.value}: JSON has no form for it)", *_place(node))
    if node.tag == _TAG + "int":
        digits, most = sum(c.isdigit() for c in node.value), sys.get_int_max_str_digits()
        if digits > most > 0:
            raise _Refused(
                f"{what} is an integer of {digits} digits: more than tumblecal reads ({most})", *_place(node)
            )


def _number(text: str, node: yaml.Node, read: Callable[[], object]) -> object:
    """An int or float as YAML 1.1 reads it (``read``); an explicit !!int or !!float of text one error."""
    try:
        return read()
    except ValueError:
        raise _Refused(f"{text[:40]!r} is not a number", *_place(node)) from None


@functools.cache
def _yaml_loader() -> type[yaml.SafeLoader]:
    """yaml.SafeLoader of JSON's values only, each meaning what it looks like (_RESOLVERS). It
    refuses aliases (``*name``: a calibration or limits file has no use for them, and a tree of
    aliases expands exponentially, a few hundred bytes to GB), any other tag (!!binary, !!set,
    !!timestamp ... which ``show --json`` and the exports could not write), a key given twice (YAML
    keeps the last), half a surrogate pair, and an integer beyond Python's 4300 digits."""
    import yaml

    class JsonValues(yaml.SafeLoader):
        def compose_node(self, parent: yaml.Node | None, index: int) -> yaml.Node | None:
            if self.check_event(yaml.events.AliasEvent):
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]
                raise yaml.composer.ComposerError(
                    None, None, "an alias (*name): tumblecal's files are read without them", mark
                )
            return super().compose_node(parent, index)

        def construct_document(self, node: yaml.Node) -> object:
            self.vet(node)
            return super().construct_document(node)

        def vet(self, root: yaml.Node) -> None:
            """Every node a JSON value, every scalar text, every mapping's keys different."""
            stack: list[tuple[yaml.Node, str]] = [(root, "")]
            while stack:
                node, where = stack.pop()
                _refuse(node, where)
                if isinstance(node, yaml.SequenceNode):
                    stack.extend((item, f"{where}[{k}]") for k, item in enumerate(node.value))
                if not isinstance(node, yaml.MappingNode):
                    continue
                seen: set[object] = set()
                for key_node, value_node in node.value:
                    _refuse(key_node, where, key=True)
                    key: object = "?"  # a list or an object as a key: the constructor refuses it
                    if isinstance(key_node, yaml.ScalarNode):
                        key = self.construct_object(key_node, deep=True)
                        if key in seen:
                            at = f" of {_field(where)}" if where else ""
                            raise _Refused(f"key {key!r}{at} is given twice: which one is meant?", *_place(key_node))
                        seen.add(key)
                    stack.append((value_node, f"{where}.{key}" if where else str(key)))

        def construct_int(self, node: yaml.ScalarNode) -> object:
            return _number(str(self.construct_scalar(node)), node, lambda: self.construct_yaml_int(node))

        def construct_float(self, node: yaml.ScalarNode) -> object:
            return _number(str(self.construct_scalar(node)), node, lambda: self.construct_yaml_float(node))

    JsonValues.add_constructor(_TAG + "int", JsonValues.construct_int)
    JsonValues.add_constructor(_TAG + "float", JsonValues.construct_float)
    JsonValues.yaml_implicit_resolvers = {}  # its own, not SafeLoader's (add_implicit_resolver copies only once)
    for tag, pattern, first in _RESOLVERS:
        JsonValues.add_implicit_resolver(_TAG + tag, re.compile(pattern), list(first))
    return JsonValues


def read_object(path: str, what: str) -> dict[str, object]:
    """The JSON/YAML object in ``path`` ('-': stdin)."""
    return parse_object(read_bytes(path, what), path, what)
