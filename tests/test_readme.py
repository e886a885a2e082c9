"""The README cannot drift: every `$` command in its console blocks runs here and its output is
compared line by line; the Python example runs and prints what its comment says; the quick-start
transcript is exactly what `make demo` runs."""

from __future__ import annotations

import contextlib
import io
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", README, flags=re.DOTALL)


def sessions() -> list[tuple[str, list[str]]]:
    """(command, expected output lines) for each `$` line of every console block."""
    out: list[tuple[str, list[str]]] = []
    for block in blocks("console"):
        for line in block.splitlines():
            if line.startswith("$ "):
                out.append((line[2:], []))
            else:
                out[-1][1].append(line)
    return out


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder like the repo root: sample_data/ and tests/data/ (linked) and an empty demo/."""
    folder = tmp_path_factory.mktemp("readme")
    (folder / "sample_data").symlink_to(ROOT / "sample_data")
    (folder / "tests").mkdir()
    (folder / "tests" / "data").symlink_to(ROOT / "tests" / "data")  # the real still captures `noise` reads
    (folder / "demo").mkdir()
    return folder


def test_readme_has_sessions() -> None:
    commands = [c for c, _ in sessions()]
    assert any(c.startswith("tumblecal solve") for c in commands)
    assert any(c.startswith("tumblecal apply") for c in commands)


@pytest.mark.parametrize(("command", "expected"), sessions(), ids=[c for c, _ in sessions()])
def test_readme_console(workdir: Path, command: str, expected: list[str]) -> None:
    if ("jq" in command or "station.sh" in command) and shutil.which("jq") is None:
        pytest.skip("jq is not installed (the station script and the --json example use it)")
    env = dict(os.environ, COLUMNS="80", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    env.pop("NO_COLOR", None)
    result = subprocess.run(
        command, shell=True, cwd=workdir, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    got = [line.rstrip() for line in result.stdout.rstrip("\n").splitlines()]
    assert got == expected


def test_readme_quick_start_is_make_demo() -> None:
    makefile = (ROOT / "Makefile").read_text()
    demo = re.findall(r'^\t"(.+?)"', makefile.split("DEMO_COMMANDS :=")[1].split("\n\n")[0], flags=re.MULTILINE)
    quick_start = [line[2:] for line in blocks("console")[0].splitlines() if line.startswith("$ ")]
    assert demo == quick_start


def test_readme_python_example(monkeypatch: pytest.MonkeyPatch, workdir: Path) -> None:
    (code,) = blocks("python")
    expected = [line[2:] for line in code.splitlines() if line.startswith("# ")]
    monkeypatch.chdir(workdir)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, "README.md", "exec"), {})
    assert printed.getvalue().splitlines() == expected


def test_readme_station_script_is_the_shipped_one() -> None:
    """The production-test section shows sample_data/station.sh as it is."""
    (script,) = blocks("sh")
    assert script == (ROOT / "sample_data" / "station.sh").read_text()
