"""The reference from where the unit was calibrated (pipeline.places, core.earth): WGS-84 normal
gravity against its published values, and --location, --gravity on solve and verify: the
reference in the calibration's units, the ``gravity`` part in the file and the summary, and bad
input as one line, exit 2, nothing written."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from tests.conftest import POSES_3, assert_untouched, assert_usage_error, precious, run, unit
from tumblecal_cli.core import earth

# NIMA TR8350.2 (3rd ed.), Table 3.3: normal gravity at the equator and at the poles (m/s^2)
EQUATOR = 9.7803253359
POLE = 9.8321849378
# Table 3.1: a; Table 3.3: b
A, B = 6378137.0, 6356752.3142


def somigliana_closed(latitude: float) -> float:
    """Somigliana's formula in its first form (TR8350.2 Eq. 4-1 before the constants k, e^2 are
    formed): (a g_e cos^2 + b g_p sin^2) / sqrt(a^2 cos^2 + b^2 sin^2), from a, b, g_e, g_p only."""
    c2, s2 = math.cos(math.radians(latitude)) ** 2, math.sin(math.radians(latitude)) ** 2
    return (A * EQUATOR * c2 + B * POLE * s2) / math.sqrt(A**2 * c2 + B**2 * s2)


@pytest.mark.parametrize(("latitude", "expected"), [(0.0, EQUATOR), (90.0, POLE), (-90.0, POLE)])
def test_normal_gravity_at_the_equator_and_the_poles_is_the_published_value(latitude: float, expected: float) -> None:
    assert abs(earth.normal_gravity(latitude) - expected) < 1e-8


@pytest.mark.parametrize("latitude", [45.0, -45.0, 30.0, 52.2, 60.0, 89.0])
def test_normal_gravity_agrees_with_somiglianas_first_form(latitude: float) -> None:
    assert abs(earth.normal_gravity(latitude) - somigliana_closed(latitude)) < 1e-8


def test_normal_gravity_at_45_degrees() -> None:
    assert earth.normal_gravity(45.0) == pytest.approx(9.806197769, abs=1e-8)


def test_height_takes_about_3_086_micro_g_per_metre_second_order_included() -> None:
    sea = earth.normal_gravity(45.0)
    # the free-air gradient, 0.3086 mGal/m, to first order; the second-order term 3 h^2/a^2 is 2.9e-7 at 2 km
    per_metre = (sea - earth.normal_gravity(45.0, 1000.0)) / 1000.0
    assert per_metre == pytest.approx(3.086e-6, rel=2e-3)
    first_order = sea * (1 - 2 / A * (1 + earth.WGS84_F + earth.WGS84_M - 2 * earth.WGS84_F * 0.5) * 2000.0)
    assert earth.normal_gravity(45.0, 2000.0) - first_order == pytest.approx(sea * 3 * 2000.0**2 / A**2, rel=1e-6)


def test_solve_at_a_location_solves_against_local_gravity_in_g(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *POSES_3, "--location", "52.2,0.12,20", "-o", out, "--json")
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    value = earth.normal_gravity(52.2, 20.0)
    assert doc["reference"] == pytest.approx(value / 9.80665, rel=1e-12)
    assert doc["units"] == "g"
    assert doc["gravity"] == {
        "latitude": 52.2,
        "longitude": 0.12,
        "height_m": 20.0,
        "value_m_s2": value,
        "source": "WGS-84 normal gravity, NIMA TR8350.2 Eqs. 4-1 and 4-3",
    }
    assert list(doc).index("gravity") == list(doc).index("input_units") + 1
    assert json.loads(r.out)["gravity"] == doc["gravity"]
    assert "reference 1.000606 g: local gravity 9.81258806 m/s^2 at 52.2, 0.12, 20.0 m" in r.err
    plain = tmp_path / "plain.json"
    assert run(capsys, "solve", "-p", *POSES_3, "-o", plain).code == 0
    gains = json.loads(plain.read_text())["gain"]  # raw per unit of reference: 1 g of 9.80665 m/s^2 before
    assert doc["gain"] == pytest.approx([g / doc["reference"] for g in gains], rel=1e-12)
    shown = run(capsys, "show", out)
    assert "local gravity 9.81258806 m/s^2" in shown.out


def test_gravity_given_in_m_s2_becomes_the_reference_in_the_units_asked(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *POSES_3, "--gravity", "9.8123", "--units", "m/s^2", "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert (doc["reference"], doc["units"]) == (9.8123, "m/s^2")
    assert doc["gravity"] == {"value_m_s2": 9.8123, "source": "given (--gravity)"}


def test_verify_at_a_location_judges_against_local_gravity(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-p", *POSES_3, "-o", cal).code == 0
    r = run(capsys, "verify", "--cal", cal, POSES_3[0], "--location", "0,0", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["reference"] == pytest.approx(EQUATOR / 9.80665, rel=1e-12)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--location", "91,0"], ["latitude 91", "-90 to 90"]),
        (["--location", "52.2"], ["--location takes LAT,LON[,HEIGHT_M]", "'52.2'"]),
        (["--location", "north,east"], ["--location takes LAT,LON[,HEIGHT_M]"]),
        (["--location", "52,0,99999"], ["height 99999 m"]),
        (["--gravity", "9.81", "--reference", "1"], ["--gravity sets the reference", "not both"]),
        (["--location", "1,2", "--reference", "1"], ["--location sets the reference", "not both"]),
        (["--location", "1,2", "--gravity", "9.81"], ["not both"]),
        (["--gravity", "1"], ["--gravity is local gravity in m/s^2", "got 1"]),
        (["--location", "1,2", "--units", "counts"], ["g or m/s^2", "'counts'"]),
        (["--location", "1,2", "--date", "2026-01-01"], ["--date is for a magnetometer"]),
        (["--date", "2026-01-01"], ["--date dates the Earth's field", "--location"]),
        (["--location", "1,2", "--sensor", "gyroscope"], ["not a gyroscope"]),
        (["--gravity", "9.81", "--sensor", "magnetometer"], ["an accelerometer's reference", "the Earth's field"]),
    ],
)
def test_bad_places_are_one_line_exit_2_and_nothing_written(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str], words: list[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "-p", *POSES_3, *args, "-o", out)
    assert_usage_error(r, *words)
    assert_untouched(out)


def test_batch_solves_every_unit_against_local_gravity(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    src = tmp_path / "units"
    unit(src, "A1", "good")
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "cals", "--location", "-33.9,18.4,40", "-q")
    assert r.code == 0, r.err
    (written,) = (tmp_path / "cals").glob("A1_*.json")
    doc = json.loads(written.read_text())
    assert doc["reference"] == pytest.approx(earth.normal_gravity(-33.9, 40.0) / 9.80665, rel=1e-12)
    assert doc["gravity"]["latitude"] == -33.9


def test_the_python_api_takes_the_place_as_the_command_line_does(tmp_path: Path) -> None:
    import tumblecal_cli as tumblecal

    solved = tumblecal.solve(POSES_3, location="-33.9,18.4,40")
    assert solved.calibration is not None
    assert solved.calibration.reference == pytest.approx(earth.normal_gravity(-33.9, 40.0) / 9.80665, rel=1e-12)
    assert solved.calibration.fields["gravity"]["latitude"] == -33.9  # type: ignore[index]
    solved.calibration.save(tmp_path / "cal.json")
    done = tumblecal.verify(POSES_3[0], str(tmp_path / "cal.json"), gravity=9.8)
    assert done.reference == pytest.approx(9.8 / 9.80665, rel=1e-12)
    again = tumblecal.load(tmp_path / "cal.json")
    assert again.fields["gravity"] == solved.calibration.fields["gravity"]  # read back and kept


@pytest.mark.parametrize(
    "args", [["--location", "91,0"], ["--sensor", "magnetometer", "--location", "1,2", "--date", "1900-01-01"]]
)
def test_batch_judges_a_bad_place_once_before_any_unit(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str]
) -> None:
    """It failed each unit with the same error and wrote the folder and a summary of errors."""
    src = tmp_path / "units"
    unit(src, "A1", "good")
    unit(src, "A2", "good")
    r = run(capsys, "batch", src, "--out-dir", tmp_path / "cals", *args)
    assert r.code == 2
    assert [line for line in r.err.splitlines() if line.startswith("error:")] == [r.err.splitlines()[0]]
    assert "A1" not in r.err
    assert not (tmp_path / "cals").exists()
