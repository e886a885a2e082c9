"""The core names no flag: its errors, findings and notes say the words about the command line by a
code (errors.Said), and pipeline.hints holds one row of words for each code, none unused."""

from __future__ import annotations

import ast
import re
import string
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import ROOT
from tumblecal_cli import errors
from tumblecal_cli.core import methods
from tumblecal_cli.core import model as core
from tumblecal_cli.errors import InputError, Said, said
from tumblecal_cli.pipeline.hints import WORDS

CORE = ROOT / "tumblecal_cli" / "core"
#: A command-line flag in a string: ``--reference``, ``--max-tilt`` (not ``x--y``, not ``---``).
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z-]+")


def _docstrings(tree: ast.AST) -> set[int]:
    """The ids of the docstring constants of a module, its classes and its functions."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            first = node.body[0] if node.body else None
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _core_trees() -> Iterator[tuple[Path, ast.Module]]:
    for path in sorted(CORE.rglob("*.py")):
        yield path, ast.parse(path.read_text(encoding="utf-8"))


def _said_calls() -> Iterator[tuple[str, str, set[str]]]:
    """Each ``said("code", fact=...)`` in the core: (where, code, the facts' names)."""
    for path, tree in _core_trees():
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "said":
                first = node.args[0] if node.args else None
                assert isinstance(first, ast.Constant), (path, node.lineno)  # a code the test can read
                assert isinstance(first.value, str), (path, node.lineno)
                names = {k.arg for k in node.keywords if k.arg is not None}
                yield f"{path.relative_to(ROOT)}:{node.lineno}", first.value, names


def test_no_string_in_the_core_names_a_flag() -> None:
    found = []
    for path, tree in _core_trees():
        docs = _docstrings(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
                found += [f"{path.relative_to(ROOT)}:{node.lineno}: {m}" for m in FLAG.findall(node.value)]
    assert found == []


def test_every_code_the_core_says_has_words_and_every_row_is_said() -> None:
    said_codes = {code for _, code, _ in _said_calls()}
    assert sorted(said_codes - WORDS.keys()) == []  # a code without words
    assert sorted(WORDS.keys() - said_codes) == []  # words no code says


def test_each_said_gives_the_facts_its_words_take() -> None:
    wrong = []
    for where, code, names in _said_calls():
        fields = {name for _, name, _, _ in string.Formatter().parse(WORDS[code]) if name is not None}
        if fields != names:
            wrong.append((where, code, sorted(names), sorted(fields)))
    assert wrong == []


def test_the_package_installs_the_words() -> None:
    assert str(said("three.reference")) == WORDS["three.reference"]
    assert f"{said('pose.short', least=10)}" == "fewer than --min-samples 10"
    assert str(said("drift.item", item="gain")) == "--max-drift 'gain' is not KEY=VALUE"


def test_without_the_words_a_said_reads_as_its_code_and_facts() -> None:
    try:
        errors.use_words({})
        assert str(said("pose.short", least=10)) == "[pose.short least=10]"
    finally:
        errors.use_words(WORDS)
    assert str(said("pose.short", least=10)) == "fewer than --min-samples 10"


def test_an_error_from_the_core_carries_its_code_and_facts() -> None:
    with pytest.raises(InputError) as caught:
        methods.pick("gyro-bias", [None], "accelerometer")
    assert str(caught.value) == "gyro-bias is a gyroscope's zero-rate bias: give --sensor gyroscope (not accelerometer)"
    assert caught.value.said == Said("gyro.sensor", (("sensor", "accelerometer"),))
    assert caught.value.said.fact("sensor") == "accelerometer"
    with pytest.raises(InputError) as three:
        core.solve_three_pose([], 0.0)
    assert three.value.said == Said("three.reference")
    assert three.value.message == "the 3-pose solver needs a positive --reference (the stimulus magnitude)"


def test_a_hint_said_by_a_code_is_the_errors_said() -> None:
    with pytest.raises(InputError) as caught:
        methods.pick("three-pose", [None, None], "accelerometer")
    assert caught.value.said is not None
    assert caught.value.said.code == "three.labels"
    assert caught.value.hint == WORDS["three.labels"]


def test_the_python_api_says_the_same_words_as_the_command_line() -> None:
    with pytest.raises(InputError) as caught:
        tumblecal.solve(np.zeros((10, 3)), method="gyro-bias")
    assert caught.value.said is not None
    assert caught.value.said.code == "gyro.sensor"
    assert "give --sensor gyroscope" in str(caught.value)
