"""The docs cannot drift: every `$` command in the console blocks of README.md and of each page under
docs/ runs here and its output is compared line by line (``make transcripts`` rewrites them after an
intended change); the Python example runs and prints what its comments say; the quick-start
transcript is exactly what `make demo` runs; the README stays short and links every page."""

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

from tests.transcripts import DOCS, ROOT, nav_pages, pages, prepare, run, sessions

pytestmark = pytest.mark.slow

README = (ROOT / "README.md").read_text(encoding="utf-8")
SESSIONS = [(page, command, expected) for page in pages() for command, expected in sessions(page.read_text("utf-8"))]


def blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.DOTALL)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return prepare(tmp_path_factory.mktemp("docs"))


def test_docs_have_sessions() -> None:
    commands = [c for _, c, _ in SESSIONS]
    assert any(c.startswith("tumblecal solve") for c in commands)
    assert any(c.startswith("tumblecal apply") for c in commands)
    assert len({page for page, _, _ in SESSIONS}) >= 10


@pytest.mark.parametrize(
    ("page", "command", "expected"),
    SESSIONS,
    ids=[f"{page.relative_to(ROOT)}: {command}" for page, command, _ in SESSIONS],
)
def test_docs_console(workdir: Path, page: Path, command: str, expected: list[str]) -> None:
    if ("jq" in command or "station.sh" in command) and shutil.which("jq") is None:
        pytest.skip("jq is not installed (the station script and the --json example use it)")
    tool = command.split()[0]
    where = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
    if tool in ("sqlite3", "sqlite-utils", "datasette") and shutil.which(tool, path=where) is None:
        pytest.skip(f"{tool} is not installed (docs/records.md reads a records database with it)")
    assert run(command, workdir) == expected


def test_readme_quick_start_is_make_demo() -> None:
    makefile = (ROOT / "Makefile").read_text()
    demo = re.findall(r'^\t"(.+?)"', makefile.split("DEMO_COMMANDS :=")[1].split("\n\n")[0], flags=re.MULTILINE)
    quick_start = [line[2:] for line in blocks(README, "console")[0].splitlines() if line.startswith("$ ")]
    assert demo == quick_start


PYTHON = [(page, code) for page in pages() for code in blocks(page.read_text("utf-8"), "python")]


@pytest.mark.parametrize(("page", "code"), PYTHON, ids=[str(page.relative_to(ROOT)) for page, _ in PYTHON])
def test_python_example(monkeypatch: pytest.MonkeyPatch, workdir: Path, page: Path, code: str) -> None:
    """Each Python example runs from the repository's root and prints what its `# ` comments say."""
    expected = [line[2:] for line in code.splitlines() if line.startswith("# ")]
    monkeypatch.chdir(workdir)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, str(page), "exec"), {})
    assert printed.getvalue().splitlines() == expected


def test_station_script_is_the_shipped_one() -> None:
    """The production-test page shows sample_data/station.sh as it is."""
    (script,) = blocks((DOCS / "production-test.md").read_text("utf-8"), "sh")
    assert script == (ROOT / "sample_data" / "station.sh").read_text()


def test_readme_is_short_and_links_every_page() -> None:
    import yaml

    assert len(README.splitlines()) < 200
    listed = nav_pages(yaml.safe_load((ROOT / "mkdocs.yml").read_text("utf-8"))["nav"])
    on_disk = sorted(str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md"))
    assert sorted(listed) == on_disk  # every page is in the site's nav, and every nav entry exists
    linked = set(re.findall(r"\]\(docs/([^)#]+)", README))
    assert set(listed) - {"index.md"} <= linked


def test_docs_site_builds_strict(tmp_path: Path) -> None:
    """mkdocs --strict: a broken link or anchor, or a page missing from the nav, fails."""
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent))
    if mkdocs is None:
        pytest.skip("mkdocs is not installed (make test installs the dev extra, which has it)")
    result = subprocess.run(
        [mkdocs, "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
