"""An export format is one registry row (tumblecal_cli/io/export/registry.py): the command line's
--format and --from choices are the registries' names, and a stand-in registered in one place
(tests/standin_export.py) is offered by the installed command line and run end to end."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import typer

from tests.conftest import POSES_3, run, with_registered
from tumblecal_cli.cli.app import app
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.export import registry

#: The command line with the stand-in registered first (tests/standin_export.py says why).


def choices(command: str, option: str) -> list[str]:
    import tumblecal_cli.cli.calfiles  # noqa: F401  (registers export and import)

    params = typer.main.get_command(app).commands[command].params  # type: ignore[attr-defined]
    (param,) = [p for p in params if option in p.opts]
    return list(param.type.choices)


def test_export_choices_are_the_registry() -> None:
    assert choices("export", "--format") == list(registry.EXPORTS)


def test_import_choices_are_the_registry() -> None:
    assert choices("import", "--from") == list(registry.IMPORTS)


def test_every_registered_format_loads_its_implementation() -> None:
    for row in registry.EXPORTS.values():
        assert callable(row.exporter()), row.name
    for imp in registry.IMPORTS.values():
        assert callable(imp.importer().claims), imp.name


def test_a_name_is_registered_once() -> None:
    with pytest.raises(ValueError, match="registered already"):
        registry.register_export(registry.EXPORTS["matlab"])
    with pytest.raises(ValueError, match="registered already"):
        registry.register_import(registry.IMPORTS["ros-yaml"])


def with_standin(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``tumblecal ARGS`` with the stand-in export registered, in a new process."""
    return with_registered("import tests.standin_export", *args)


@pytest.fixture(scope="module")
def solved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    cal = tmp_path_factory.mktemp("standin") / "cal.json"
    from tests.conftest import tumblecal

    assert tumblecal("solve", "--poses", *POSES_3, "-q", "-o", cal).code == 0
    return cal


def expected(cal: Path) -> str:
    """What the stand-in writes, from the calibration read here."""
    c = calfile.load(str(cal))
    return f"standin {c.sensor} {c.method} {' '.join(repr(float(v)) for v in c.offset)}\n"


def test_the_command_line_offers_the_standin() -> None:
    shown = with_standin("export", "--help")
    assert shown.returncode == 0, shown.stderr
    assert "|px4|standin>" in shown.stdout
    assert "standin: one line of the sensor" in " ".join(shown.stdout.split())


def test_the_standin_writes_its_file_atomically(solved: Path) -> None:
    out = solved.parent / "out.txt"
    out.write_text("what was there\n")
    done = with_standin("export", "--format", "standin", solved, "-o", out)
    assert done.returncode == 0, done.stderr
    assert out.read_text() == expected(solved)
    assert done.stdout == ""
    assert done.stderr == "note: the stand-in wrote one line\n"
    assert sorted(p.name for p in solved.parent.iterdir()) == ["cal.json", "out.txt"]  # no temp file left


def test_the_standin_writes_stdout(solved: Path) -> None:
    done = with_standin("export", "--format", "standin", solved, "-o", "-")
    assert done.returncode == 0, done.stderr
    assert done.stdout == expected(solved)


def test_an_option_the_standin_does_not_take_leaves_the_output(solved: Path) -> None:
    out = solved.parent / "kept.txt"
    out.write_text("what was there\n")
    done = with_standin("export", "--format", "standin", solved, "--prefix", "imu", "-o", out)
    assert done.returncode == 2
    assert done.stderr.startswith("error: --prefix is for --format c-header\n")
    assert out.read_text() == "what was there\n"


def test_without_the_registration_there_is_no_standin(capsys: pytest.CaptureFixture[str], solved: Path) -> None:
    r = run(capsys, "export", "--format", "standin", solved)
    assert r.code == 2
    assert "'standin' is not one of" in r.err
