"""One units vocabulary (tumblecal_cli/core/quantities.py): every command that converts units reads it,
standard gravity is defined once, and a gyroscope calibrated in mdps exports as one in deg/s does."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import ROOT, imported, run
from tumblecal_cli.core import quantities as units
from tumblecal_cli.io.calfiles.calfile import Calibration
from tumblecal_cli.io.export import paramfile
from tumblecal_cli.pipeline import noise


def test_the_vocabulary_imports_no_numpy() -> None:
    assert imported("import tumblecal_cli.core.quantities", ("numpy",)) == []


def test_standard_gravity_is_defined_once() -> None:
    """The number 9.80665 is in the package's code once, in core.quantities (help texts may say it)."""
    found = [
        str(path.relative_to(ROOT))
        for path in sorted((ROOT / "tumblecal_cli").rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Constant) and isinstance(node.value, float) and math.isclose(node.value, 9.80665)
    ]
    assert found == ["tumblecal_cli/core/quantities.py"]


@pytest.mark.parametrize(
    ("sensor", "name", "factor"),
    [
        ("accelerometer", "g", 9.80665),
        ("accelerometer", "mg", 9.80665e-3),
        ("accelerometer", "m/s²", 1.0),
        ("gyroscope", "deg/s", math.pi / 180),
        ("gyroscope", "mdps", math.pi / 180e3),
        ("gyroscope", "degree/s", math.pi / 180),
        ("magnetometer", "uT", 1e-2),
        ("magnetometer", "µT", 1e-2),
        ("magnetometer", "mG", 1e-3),
        ("magnetometer", "nT", 1e-5),
    ],
)
def test_each_name_has_its_factor_to_the_base_unit(sensor: str, name: str, factor: float) -> None:
    assert units.factor(sensor, name) == factor


def test_a_name_of_another_quantity_is_not_known() -> None:
    assert units.factor("magnetometer", "g") is None  # milli-g is not milligauss
    assert units.factor("accelerometer", "mG") is None
    assert units.factor("gyroscope", "counts") is None


def test_noise_and_export_read_the_same_names() -> None:
    """Every name noise converts (folded to lower case) export converts too, by the same factor."""
    for sensor in noise.FIGURED:
        for name in units.names(sensor):
            assert noise.to_si(sensor, name.upper()) == units.factor(sensor, name)
        assert set(units.COMMON[units.QUANTITY[sensor]]) <= set(units.names(sensor))


def gyroscope(unit: str, offset: list[float]) -> Calibration:
    """A gyroscope's bias calibration in ``unit``, raw and corrected."""
    return Calibration(
        sensor="gyroscope",
        method="gyro-bias",
        reference=0.0,
        columns=["x", "y", "z"],
        offset=np.array(offset),
        matrix=np.eye(3),
        gain=np.ones(3),
        units=unit,
        input_units=unit,
        path="cal.json",
    )


def parameters(text: str, sep: str) -> dict[str, str]:
    rows = [line.split(sep) for line in text.splitlines() if line and not line.startswith("#")]
    return {row[-3] if sep == "\t" else row[0]: row[-2] if sep == "\t" else row[1] for row in rows}


def test_an_mdps_gyroscope_exports_in_rad_per_second() -> None:
    """500 mdps is 0.5 deg/s is 0.5 pi / 180 = 0.00872664626 rad/s (-300 mdps: -0.00523598776;
    200 mdps: 0.0034906585): ArduPilot's INS_GYROFFS and PX4's CAL_GYRO_xOFF, as written by hand."""
    cal = gyroscope("mdps", [500.0, -300.0, 200.0])
    expected = ["0.00872664626", "-0.00523598776", "0.0034906585"]
    ap = parameters(paramfile.write(cal, "ardupilot", 1).text, ",")
    assert ap == {f"INS_GYROFFS_{axis}": value for axis, value in zip("XYZ", expected, strict=True)}
    px4 = parameters(paramfile.write(cal, "px4", 0).text, "\t")
    assert px4 == {f"CAL_GYRO0_{axis}OFF": value for axis, value in zip("XYZ", expected, strict=True)}


@pytest.mark.parametrize("fmt", ["ardupilot", "px4"])
def test_mdps_exports_as_deg_per_second_does(fmt: str) -> None:
    """The same offsets in mdps and in deg/s give the same parameters (the comments say the units)."""
    sep = "," if fmt == "ardupilot" else "\t"
    in_mdps = parameters(paramfile.write(gyroscope("mdps", [500.0, -300.0, 250.0]), fmt, 1).text, sep)
    in_dps = parameters(paramfile.write(gyroscope("deg/s", [0.5, -0.3, 0.25]), fmt, 1).text, sep)
    assert in_mdps.keys() == in_dps.keys()
    for name, value in in_mdps.items():
        assert float(value) == pytest.approx(float(in_dps[name]), rel=1e-8)


def test_export_of_an_mdps_calibration_on_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The calibration that noise reads in mdps, export writes for ArduPilot (exit 2 before)."""
    cal = tmp_path / "gyro.json"
    gyroscope("mdps", [500.0, -300.0, 200.0]).save(str(cal))
    r = run(capsys, "export", str(cal), "--format", "ardupilot")
    assert r.code == 0, r.err
    assert "INS_GYROFFS_X,0.00872664626" in r.out.splitlines()
    assert "# units: mdps in and out, x 1.74532925e-05 to rad/s" in r.out.splitlines()
