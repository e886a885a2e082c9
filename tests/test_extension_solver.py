"""The solver catalog is the one place a solver is added (core.catalog): every row complete, the
command line's ``--method`` choices and help its names, and a stand-in solver registered in one
place (tests/standin_solver.py: its row and its function) offered and run end to end by the
command line: solve writes its calibration, show and check read it back, apply applies it."""

from __future__ import annotations

import inspect
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import tumblecal, with_registered, write
from tests.synth import pose_samples
from tumblecal_cli.core import catalog
from tumblecal_cli.core.model import FACES
from tumblecal_cli.errors import InputError
from tumblecal_cli.pipeline import options

#: The console script's entry point, with the stand-in's row registered before the command line
#: is imported (tests/standin_solver.py).
OFFSET = np.array([0.031, -0.022, 0.047])
GAIN = np.array([1.021, 0.984, 1.008])


def standin_cli(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``tumblecal ARGS`` with the stand-in solver registered, in a new process."""
    return with_registered("import tests.standin_solver", *args)


def test_the_method_choices_are_the_catalogs_names() -> None:
    from tumblecal_cli.cli.flags import MethodName, method_help

    assert [m.value for m in MethodName] == ["auto", *catalog.names()]
    assert method_help().endswith(": docs/commands/solve.md), " + ", ".join(catalog.names()) + ".")
    for name in catalog.names():  # the Python API takes the same choices
        options.choices_and_numbers({"method": name})
    with pytest.raises(InputError, match="is not one of auto, one-pose"):
        options.choices_and_numbers({"method": "standin"})


@pytest.mark.parametrize("row", catalog.rows(), ids=lambda row: row.name)
def test_every_row_is_complete(row: catalog.Method) -> None:
    function = catalog.solver(row.name)
    assert callable(function)
    if row.takes != "turns":  # fits.fit calls it with one SolverInput
        assert len(inspect.signature(function).parameters) == 1
    assert row.source.strip()
    assert row.help.strip()
    assert row.sensors
    assert set(row.sensors) <= set(catalog.SENSORS)
    assert row.takes in catalog.TAKES
    assert {n.limit for n in row.not_applying} <= set(catalog.LIMITS)
    # the limits its flags rule out are said not to apply, and no others of those
    assert (catalog.GAINS_FIXED in row.not_applying) == (not row.fits_gains)
    assert row.fits_gains or catalog.NO_CROSS_AXIS in row.not_applying
    assert (catalog.TURNED_NOISE in row.not_applying) == row.turned
    assert not row.turned or row.takes == "samples"


def test_a_name_is_registered_once() -> None:
    six = catalog.find("six-pose")
    assert six is not None
    for taken in ("six-pose", "auto"):
        with pytest.raises(ValueError, match="registered already"):
            catalog.register(six._replace(name=taken))
    assert catalog.names().count("six-pose") == 1


def test_the_installed_command_line_does_not_know_the_standin() -> None:
    """Without its registration, the stand-in is no choice: what offers it is the one row."""
    code, _, err = tumblecal("solve", "--poses", "x.csv", "--method", "standin")
    assert code == 2
    assert "'standin' is not one of 'auto', 'one-pose'" in err


def _six_faces(folder: Path) -> list[str]:
    """Six pose files of a unit with OFFSET and GAIN, labelled with their faces."""
    rng = np.random.default_rng(7)
    items = []
    for face in ("+x", "-x", "+y", "-y", "+z", "-z"):
        raw = pose_samples(rng, FACES[face], offset=OFFSET, gain=GAIN, reference=1.0, noise=0.002, n=400)
        path = write(folder / f"{face[1]}{'p' if face[0] == '+' else 'n'}.csv", raw, header="x,y,z", fmt="%.6f")
        items.append(f"{face}={path}")
    return list(reversed(items))  # any order: the six-pose family's check puts them in its own


@pytest.mark.slow
def test_a_standin_solver_registered_in_one_place_runs_end_to_end(tmp_path: Path) -> None:
    shown = standin_cli("solve", "--help")
    assert shown.returncode == 0, shown.stderr
    assert "ferraris-turns, known-rates, rotations, standin." in " ".join(shown.stdout.split())

    cal = tmp_path / "unit.json"
    solved = standin_cli("solve", "--poses", *_six_faces(tmp_path), "--method", "standin", "-o", cal)
    assert solved.returncode == 0, solved.stderr
    doc = json.loads(cal.read_text())
    assert doc["method"] == "standin"
    assert [p["pose"] for p in doc["poses"]] == ["+x", "-x", "+y", "-y", "+z", "-z"]
    np.testing.assert_allclose(doc["offset"], OFFSET, atol=1e-3)
    np.testing.assert_allclose(doc["gain"], GAIN, atol=1e-3)

    show = standin_cli("show", cal)
    assert show.returncode == 0, show.stderr
    assert "standin" in show.stdout + show.stderr

    limits = write(tmp_path / "limits.json", {"offset": 0.05, "gain_error": 0.03, "cross_axis": 0.01})
    judged = standin_cli("check", cal, "--limits", limits)
    assert judged.returncode == 0, judged.stderr
    assert "the standin solver estimates no cross-axis terms, so the cross-axis limit does not apply" in " ".join(
        judged.stderr.split()
    )
    assert standin_cli("check", cal, "--max-offset", "0.01", "-q").returncode == 1

    truth = np.array([[0.6, 0.0, 0.8], [0.0, -1.0, 0.0]])
    capture = write(tmp_path / "capture.csv", truth * GAIN + OFFSET, header="x,y,z", fmt="%.6f")
    applied = standin_cli("apply", "--cal", cal, capture)
    assert applied.returncode == 0, applied.stderr
    rows = np.loadtxt(applied.stdout.splitlines()[1:], delimiter=",")
    np.testing.assert_allclose(rows, truth, atol=2e-3)
