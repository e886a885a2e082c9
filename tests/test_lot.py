"""Lot statistics (tumblecal_cli/core/lot.py; the report's files in tumblecal_cli/pipeline/report.py):
known answers for Cpk, modified z, the lot's members, drift, and the report's cells, from
calibration files written into tmp_path."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import write
from tumblecal_cli.core import lot
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles import calfile, limitfile
from tumblecal_cli.pipeline import report as reports

Vec = tuple[float, float, float]


def document(
    *,
    serial: str | int | None = "SN1",
    created: str | None = "2024-05-01T10:00:00Z",
    offset: Vec = (0.01, -0.02, 0.03),
    gain: Vec = (1.0, 1.0, 1.0),
    cross: list[list[float]] | None = None,
    method: str = "three-pose",
    sensor: str = "accelerometer",
) -> dict[str, Any]:
    """A minimal valid calibration: A = diag(gain) + cross (off-diagonal terms), M = A⁻¹."""
    a = np.diag(gain) + (np.array(cross) if cross is not None else 0.0)
    m = np.linalg.inv(a)
    doc: dict[str, Any] = {
        "format": calfile.FORMAT,
        "version": calfile.VERSION,
        "sensor": sensor,
        "method": method,
        "reference": 1.0,
        "columns": ["ax", "ay", "az"],
        "offset": list(offset),
        "matrix": [[float(v) for v in row] for row in m],
        "gain": [float(v) for v in np.diag(a)],
        "unit": {"serial": serial, "station": "bay-1", "operator": None, "meta": {}},
    }
    if created is not None:
        doc["created"] = created
    return doc


def loaded(tmp_path: Path, name: str = "cal.json", **fields: Any) -> lot.Entry:
    return reports.entry(calfile.load(str(write(tmp_path / name, document(**fields)))))


def standardised(n: int, seed: int = 1) -> np.ndarray[Any, np.dtype[np.float64]]:
    """n values with mean exactly 0 and sample standard deviation (ddof=1) exactly 1."""
    x = np.random.default_rng(seed).normal(size=n)
    x -= x.mean()
    out: np.ndarray[Any, np.dtype[np.float64]] = x / x.std(ddof=1)
    return out


# --- Cpk -----------------------------------------------------------------------------------------


def test_cpk_matches_a_hand_computation() -> None:
    x = 0.01 + 0.005 * standardised(25)
    assert float(np.mean(x)) == pytest.approx(0.01)
    assert float(np.std(x, ddof=1)) == pytest.approx(0.005)
    assert lot.cpk(x, -0.05, 0.05) == pytest.approx(0.04 / 0.015)  # the nearer limit: USL − μ = 0.04


def test_cpk_is_one_sided_with_one_limit() -> None:
    x = 0.01 + 0.005 * standardised(25)
    assert lot.cpk(x, None, 0.05) == pytest.approx(0.04 / 0.015)  # CPU
    assert lot.cpk(x, -0.05, None) == pytest.approx(0.06 / 0.015)  # CPL = 4


@pytest.mark.parametrize(
    ("values", "lower", "upper"),
    [
        pytest.param([0.01], -0.05, 0.05, id="one-value"),
        pytest.param([], -0.05, 0.05, id="no-values"),
        pytest.param([0.01, 0.01, 0.01], -0.05, 0.05, id="zero-sigma"),
        pytest.param([0.01, 0.02, 0.03], None, None, id="no-limit"),
    ],
)
def test_cpk_is_none_when_it_is_undefined(values: list[float], lower: float | None, upper: float | None) -> None:
    assert lot.cpk(values, lower, upper) is None


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    shift=st.floats(-100, 100, allow_nan=False),
    half_width=st.floats(0.5, 10),
)
def test_cpk_is_invariant_to_shifting_values_and_limits_together(seed: int, shift: float, half_width: float) -> None:
    x = np.random.default_rng(seed).normal(0.1, 0.2, size=20)
    assert lot.cpk(x + shift, shift - half_width, shift + half_width) == pytest.approx(
        lot.cpk(x, -half_width, half_width), rel=1e-6, abs=1e-9
    )


# --- modified z ----------------------------------------------------------------------------------


def test_robust_z_matches_a_hand_computation() -> None:
    # median 3, |deviations| 2 1 0 1 97 → MAD 1
    assert lot.robust_z([1, 2, 3, 4, 100]) == pytest.approx(0.6745 * np.array([-2, -1, 0, 1, 97]))


def test_robust_z_flags_a_planted_outlier_and_no_normal_value() -> None:
    x = np.append(np.random.default_rng(7).normal(0.0, 1.0, size=30), 9.0)
    z = lot.robust_z(x)
    assert abs(z[-1]) > lot.OUTLIER_Z
    assert (np.abs(z[:-1]) <= lot.OUTLIER_Z).all()


def test_robust_z_falls_back_to_the_mean_absolute_deviation_when_mad_is_zero() -> None:
    x = [1.0] * 29 + [2.0]  # MAD 0; MeanAD = 1/30
    z = lot.robust_z(x)
    assert z[-1] == pytest.approx(1.0 / (1.253314 / 30))
    assert (z[:-1] == 0).all()


def test_robust_z_is_zero_when_all_values_are_equal() -> None:
    assert (lot.robust_z([0.5] * 5) == 0).all()
    assert len(lot.robust_z([])) == 0


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16), scale=st.floats(1e-3, 1e3), shift=st.floats(-1e3, 1e3))
def test_robust_z_is_invariant_to_scale_and_shift(seed: int, scale: float, shift: float) -> None:
    x = np.random.default_rng(seed).normal(size=15)
    assert lot.robust_z(scale * x + shift) == pytest.approx(lot.robust_z(x), rel=1e-6, abs=1e-6)


# --- files ---------------------------------------------------------------------------------------


def test_find_searches_folders_recursively_and_skips_hidden_names(tmp_path: Path) -> None:
    write(tmp_path / "cals" / "b.json", "{}")
    write(tmp_path / "cals" / "a.YAML", "{}")
    write(tmp_path / "cals" / "deep" / "c.yml", "{}")
    write(tmp_path / "cals" / ".SN1.abc.partial.json", "{}")  # batch's staging file
    write(tmp_path / "cals" / ".hidden" / "d.json", "{}")
    write(tmp_path / "cals" / "summary.csv", "serial\n")
    single = str(write(tmp_path / "other" / "one.txt", "{}"))  # named explicitly: taken whatever its suffix
    root = str(tmp_path / "cals")
    assert reports.find([root, single, str(tmp_path / "cals" / "b.json")]) == sorted(
        [f"{root}/a.YAML", f"{root}/b.json", f"{root}/deep/c.yml", single]
    )


def test_find_refuses_a_missing_path(tmp_path: Path) -> None:
    (tmp_path / "cals").mkdir()
    with pytest.raises(InputError, match="nope: no such file or folder"):
        reports.find([str(tmp_path / "cals"), str(tmp_path / "nope")])


def test_find_refuses_a_folder_without_calibration_files(tmp_path: Path) -> None:
    write(tmp_path / "cals" / "notes.txt", "x")
    write(tmp_path / "cals" / ".partial.json", "{}")
    with pytest.raises(InputError, match=r"no calibration files \(\*\.json, \*\.yaml\) in .*cals"):
        reports.find([str(tmp_path / "cals")])


def test_load_all_collects_unreadable_files_and_goes_on(tmp_path: Path) -> None:
    good = str(write(tmp_path / "SN1.json", document()))
    other = str(write(tmp_path / "package.json", json.dumps({"name": "not-a-calibration"})))
    broken = str(write(tmp_path / "SN2.json", '{"format": '))
    entries, unreadable = reports.load_all([str(tmp_path)])
    assert [e.path for e in entries] == [good]
    assert dict(unreadable) == {
        other: "not a tumblecal calibration: missing field 'format' (expected 'tumblecal-calibration')",
        broken: "not valid JSON: Expecting value (line 1, column 12)",
    }
    report = lot.summarise(entries, unreadable, {}, max_drift={})
    assert (report.files, report.units, report.unreadable) == (3, 1, unreadable)


# --- one calibration -----------------------------------------------------------------------------


def test_entry_of_a_three_pose_calibration_has_offsets_and_gains(tmp_path: Path) -> None:
    e = loaded(tmp_path, offset=(0.01, -0.02, 0.03), gain=(1.01, 0.99, 1.02))
    assert (e.serial, e.created, e.sensor, e.method) == ("SN1", "2024-05-01T10:00:00Z", "accelerometer", "three-pose")
    assert e.values == pytest.approx(
        {"offset.x": 0.01, "offset.y": -0.02, "offset.z": 0.03, "gain.x": 1.01, "gain.y": 0.99, "gain.z": 1.02}
    )


@pytest.mark.parametrize("method", ["one-pose", "one-pose-tilt", "gyro-bias", "minmax"])
def test_fixed_gain_methods_have_no_gains(tmp_path: Path, method: str) -> None:
    assert sorted(loaded(tmp_path, method=method).values) == ["offset.x", "offset.y", "offset.z"]


def test_cross_terms_only_when_the_matrix_has_off_diagonal_terms(tmp_path: Path) -> None:
    cross = [[0.0, 0.01, -0.02], [0.005, 0.0, 0.0], [0.0, 0.03, 0.0]]
    e = loaded(tmp_path, method="six-pose", gain=(2.0, 1.0, 0.5), cross=cross)
    assert e.values == pytest.approx(
        {
            "offset.x": 0.01,
            "offset.y": -0.02,
            "offset.z": 0.03,
            "gain.x": 2.0,
            "gain.y": 1.0,
            "gain.z": 0.5,
            "cross.xy": 0.01 / 2.0,
            "cross.xz": -0.02 / 2.0,
            "cross.yx": 0.005 / 1.0,
            "cross.yz": 0.0,
            "cross.zx": 0.0,
            "cross.zy": 0.03 / 0.5,
        }
    )
    assert not any(k.startswith("cross.") for k in loaded(tmp_path, "diag.json", method="six-pose").values)


def test_entry_reads_a_hand_written_yaml_file(tmp_path: Path) -> None:
    text = calfile.dumps(document(serial=None), "cal.yaml")
    text = text.replace("serial: null", "serial: 1234").replace("'2024-05-01T10:00:00Z'", "2024-05-01T10:00:00Z")
    e = reports.entry(calfile.load(str(write(tmp_path / "cal.yaml", text))))
    assert (e.serial, e.created) == ("1234", "2024-05-01T10:00:00Z")  # an int serial, an unquoted timestamp


def test_entry_without_serial_or_created(tmp_path: Path) -> None:
    e = loaded(tmp_path, serial=None, created=None)
    assert (e.serial, e.created) == (None, "")


# --- bounds --------------------------------------------------------------------------------------


def test_bounds_from_a_limits_file(tmp_path: Path) -> None:
    path = write(
        tmp_path / "limits.yaml",
        "offset: [0.05, 0.06, 0.07]\ngain_error: 0.02\nnominal_gain: [2048, 2048, 1024]\ncross_axis: 0.01\n",
    )
    limits = limitfile.load_limits(str(path))
    assert lot.bounds("offset.y", limits) == pytest.approx((-0.06, 0.06))
    assert lot.bounds("gain.z", limits) == pytest.approx((1024 * 0.98, 1024 * 1.02))
    assert lot.bounds("cross.zx", limits) == pytest.approx((-0.01, 0.01))
    assert lot.bounds("offset.x", {}) == (None, None)
    assert lot.bounds("gain.x", {"gain_error": 0.01}) == pytest.approx((0.99, 1.01))  # nominal 1
    assert lot.bounds("gain.x", {"nominal_gain": 2.0}) == (None, None)  # a nominal bounds nothing alone


# --- the lot and its drift -----------------------------------------------------------------------


def test_a_unit_calibrated_three_times_counts_once_with_its_newest(tmp_path: Path) -> None:
    # the paths' order is not the calibrations' order: created decides
    write(tmp_path / "a.json", document(created="2024-05-03T09:00:00Z", offset=(0.03, 0, 0)))  # newest
    write(tmp_path / "b.json", document(created="2024-05-01T09:00:00Z", offset=(0.01, 0, 0)))
    write(tmp_path / "c.json", document(created="2024-05-02T09:00:00Z", offset=(0.02, 0, 0)))
    write(tmp_path / "d.json", document(serial="SN2", offset=(0.05, 0, 0)))
    write(tmp_path / "e.json", document(serial=None, offset=(0.07, 0, 0)))
    write(tmp_path / "f.json", document(serial=None, offset=(0.07, 0, 0)))  # no serial: each on its own
    write(tmp_path / "g.json", document(sensor="magnetometer", method="ellipsoid", offset=(5.0, 0, 0)))
    entries, _ = reports.load_all([str(tmp_path)])
    report = lot.summarise(entries, [], {}, max_drift={})
    assert (report.files, report.units) == (7, 5)
    row = next(r for r in report.rows if (r.sensor, r.parameter) == ("accelerometer", "offset.x"))
    assert row.count == 4
    assert row.mean == pytest.approx((0.03 + 0.05 + 0.07 + 0.07) / 4)
    assert (row.min, row.max) == pytest.approx((0.03, 0.07))
    assert [r.parameter for r in report.rows if r.sensor == "accelerometer"] == [*lot.OFFSETS, *lot.GAINS]
    magnetometer = [r for r in report.rows if r.sensor == "magnetometer"]
    assert (magnetometer[0].parameter, magnetometer[0].count, magnetometer[0].std) == ("offset.x", 1, None)


def test_drift_compares_the_latest_with_the_one_before_and_judges_gain_relative(tmp_path: Path) -> None:
    write(tmp_path / "SN1_1.json", document(created="2024-05-01T09:00:00Z", offset=(0.0, 0.0, 0.0), gain=(2, 1, 1)))
    write(tmp_path / "SN1_2.json", document(created="2024-05-02T09:00:00Z", offset=(0.01, 0.0, 0.0), gain=(2, 1, 1)))
    write(
        tmp_path / "SN1_3.json",
        document(created="2024-05-03T09:00:00Z", offset=(0.025, 0.0, 0.0), gain=(2.003, 1.003, 1.0)),
    )
    write(tmp_path / "SN2.json", document(serial="SN2"))  # calibrated once: no drift
    entries, _ = reports.load_all([str(tmp_path)])
    drift = lot.summarise(entries, [], {}, max_drift={"offset": 0.01, "gain": 0.002}).drift
    assert {d.serial for d in drift} == {"SN1"}
    assert [d.parameter for d in drift] == [*lot.OFFSETS, *lot.GAINS]
    by = {d.parameter: d for d in drift}
    x = by["offset.x"]
    assert (x.previous, x.latest) == (str(tmp_path / "SN1_2.json"), str(tmp_path / "SN1_3.json"))
    assert (x.previous_created, x.latest_created) == ("2024-05-02T09:00:00Z", "2024-05-03T09:00:00Z")
    assert x.change == pytest.approx(0.015)
    assert (x.limit, x.flagged, x.relative) == (0.01, True, None)
    assert not by["offset.y"].flagged
    # the same absolute change 0.003: 0.15 % of a gain of 2 passes, 0.3 % of a gain of 1 does not
    gx, gy = by["gain.x"], by["gain.y"]
    assert [gx.change, gx.relative, gy.change, gy.relative] == pytest.approx([0.003, 0.0015, 0.003, 0.003])
    assert (gx.flagged, gy.flagged, gx.limit) == (False, True, 0.002)
    unlimited = lot.summarise(entries, [], {}, max_drift={}).drift
    assert not any(d.flagged or d.limit is not None for d in unlimited)


def test_drift_of_cross_terms_against_the_cross_limit(tmp_path: Path) -> None:
    write(tmp_path / "1.json", document(method="six-pose", created="2024-01-01T00:00:00Z", cross=[[0, 0.01, 0]] * 3))
    write(tmp_path / "2.json", document(method="six-pose", created="2024-02-01T00:00:00Z", cross=[[0, 0.03, 0]] * 3))
    entries, _ = reports.load_all([str(tmp_path)])
    flagged = [d.parameter for d in lot.summarise(entries, [], {}, max_drift={"cross": 0.01}).drift if d.flagged]
    assert flagged == ["cross.xy", "cross.zy"]  # cross.yy is the diagonal: A[i, j] for i != j only


# --- --max-drift ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (None, {}),
        ("offset=0.01,gain=0.002,cross=0.001", {"offset": 0.01, "gain": 0.002, "cross": 0.001}),
        (" gain = 2e-3 ", {"gain": 0.002}),
        ("cross_axis=0.001", {"cross": 0.001}),
    ],
)
def test_parse_max_drift_reads_any_subset(text: str | None, expected: dict[str, float]) -> None:
    assert lot.parse_max_drift(text) == expected


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0.01", "not KEY=VALUE"),
        ("offset=0.01,0.002", "not KEY=VALUE"),
        ("noise=0.01", "unknown key 'noise'"),
        ("offset=0", "must be a positive number"),
        ("gain=-0.1", "must be a positive number"),
        ("gain=nan", "must be a positive number"),
        ("gain=abc", "is not a number"),
        ("cross=0.1,cross_axis=0.2", "given twice"),
        ("", "is empty"),
    ],
)
def test_parse_max_drift_refuses_bad_forms_with_a_hint(text: str, message: str) -> None:
    with pytest.raises(InputError, match=message) as caught:
        lot.parse_max_drift(text)
    assert caught.value.hint == lot.DRIFT_HINT


# --- the report ----------------------------------------------------------------------------------


SPREAD = [0.010, 0.011, 0.009, 0.012, 0.008, 0.010, 0.060, 0.011, 0.009, 0.010] + [0.008, 0.012, 0.010] * 10


def lot_folder(tmp_path: Path) -> list[lot.Entry]:
    """Forty units (enough to judge outliers) whose offset.x spreads by a few mg, one unit (SN7) far
    off, and SN3 twice."""
    for k, x in enumerate(SPREAD, start=1):
        write(tmp_path / f"SN{k}.json", document(serial=f"SN{k}", offset=(x, 0.0, 0.0)))
    write(tmp_path / "SN3_old.json", document(serial="SN3", created="2024-04-01T00:00:00Z", offset=(-0.02, 0.0, 0.0)))
    entries, unreadable = reports.load_all([str(tmp_path)])
    assert unreadable == []
    return entries


def test_the_report_finds_the_outlier_and_its_csv_cells(tmp_path: Path) -> None:
    limits = {"offset": np.full(3, 0.05), "gain_error": np.full(3, 0.02)}
    report = lot.summarise(lot_folder(tmp_path), [], limits, max_drift={"offset": 0.01})
    assert (report.files, report.units) == (41, 40)
    row = report.rows[0]
    assert (row.sensor, row.parameter, row.count, row.lower, row.upper) == (
        "accelerometer",
        "offset.x",
        40,
        -0.05,
        0.05,
    )
    [(unit, value, t)] = row.outliers
    assert (unit, value) == ("SN7", 0.06)
    others = np.array([x for x in SPREAD if x != 0.06])
    assert t == pytest.approx((0.06 - others.mean()) / (others.std(ddof=1) * math.sqrt(1 + 1 / 39)))
    assert report.needs_attention
    header, rows = report.csv_rows()
    assert ",".join(header) == (
        "sensor,parameter,count,mean,std,min,max,lower,upper,cpk,outliers,drift_flagged,outside,outlier_rule,cpk_low,cpk_high"
    )
    assert len(rows) == len(report.rows) == 6
    cells = dict(zip(header, rows[0], strict=True))
    assert cells["count"] == "40"
    assert cells["mean"] == repr(row.mean)
    assert float(cells["mean"]) == row.mean  # full precision
    assert (cells["min"], cells["max"], cells["lower"], cells["upper"]) == ("0.008", "0.06", "-0.05", "0.05")
    assert cells["cpk"] == repr(row.cpk)
    assert cells["outliers"] == f"SN7={t:.1f}" == "SN7=31.7"
    assert cells["outlier_rule"] == f"|t|>{row.outlier_limit:.3g} (alpha 0.005 over 240)"
    assert cells["drift_flagged"] == "SN3"  # -0.02 → 0.009: moved 0.029 > 0.01
    assert cells["outside"] == "SN7"  # 0.06 > 0.05
    y = dict(zip(header, rows[1], strict=True))
    assert (y["std"], y["cpk"], y["outliers"], y["drift_flagged"]) == ("0.0", "", "", "")  # σ = 0: no Cpk


def test_outliers_without_a_serial_are_named_by_their_file(tmp_path: Path) -> None:
    for k in range(40):
        write(tmp_path / f"u{k}.json", document(serial=None, offset=(0.01 + 0.001 * (k % 3), 0, 0)))
    write(tmp_path / "odd.json", document(serial=None, offset=(0.5, 0, 0)))
    entries, _ = reports.load_all([str(tmp_path)])
    assert [u for u, _, _ in lot.summarise(entries, [], {}, max_drift={}).rows[0].outliers] == ["odd.json"]


def test_needs_attention_for_a_cpk_below_the_minimum(tmp_path: Path) -> None:
    for k, x in enumerate([0.01, 0.02, 0.03, 0.04], start=1):
        write(tmp_path / f"SN{k}.json", document(serial=f"SN{k}", offset=(x, 0.0, 0.0)))
    entries, _ = reports.load_all([str(tmp_path)])
    limits = {"offset": np.full(3, 0.05)}
    relaxed = lot.summarise(entries, [], limits, max_drift={})
    assert not relaxed.needs_attention
    cpk = relaxed.rows[0].cpk
    assert cpk is not None
    assert cpk == pytest.approx((0.05 - 0.025) / (3 * float(np.std([0.01, 0.02, 0.03, 0.04], ddof=1))))
    assert lot.summarise(entries, [], limits, max_drift={}, min_cpk=cpk + 0.01).needs_attention
    assert not lot.summarise(entries, [], limits, max_drift={}, min_cpk=cpk - 0.01).needs_attention


def test_as_dict_is_plain_json(tmp_path: Path) -> None:
    entries = lot_folder(tmp_path)
    unreadable = [(str(tmp_path / "bad.json"), "not valid JSON")]
    report = lot.summarise(entries, unreadable, {"cross_axis": 0.01}, max_drift={"gain": 0.002}, min_cpk=1.33)
    text = json.dumps(report.as_dict(), allow_nan=False)  # no numpy types, no NaN
    back = json.loads(text)
    assert (back["files"], back["units"], back["min_cpk"], back["needs_attention"]) == (42, 40, 1.33, True)
    assert back["parameters"][0]["outliers"] == [
        {"unit": "SN7", "value": 0.06, "t": pytest.approx(31.73, abs=0.005)},
    ]
    assert back["outlier_rule"]["alpha"] == 0.005
    assert back["outlier_rule"]["tests"] == 240
    assert back["parameters"][0]["cpk"] is None  # no offset limit given
    assert {d["serial"] for d in back["drift"]} == {"SN3"}
    assert back["unreadable"] == [{"file": unreadable[0][0], "error": "not valid JSON"}]
    assert all(isinstance(v, float | int | str | bool | type(None)) for v in back["drift"][0].values())
    assert not math.isnan(back["parameters"][1]["mean"])


def test_sigterm_while_loading_stops_the_report(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """An interrupted load is not an unreadable file: the report stops (exit 130 in main)."""
    from tumblecal_cli.errors import Interrupted

    (tmp_path / "a.json").write_text("{}")

    def interrupted(path: str) -> None:
        raise Interrupted("interrupted (SIGTERM)")

    monkeypatch.setattr(calfile, "load", interrupted)
    with pytest.raises(Interrupted):
        reports.load_all([str(tmp_path)])


def test_cpk_interval_is_bissells_and_covers_the_true_cpk() -> None:
    low, high = lot.cpk_interval(1.33, 30)
    half = 1.959964 * math.sqrt(1 / 270 + 1.33**2 / 58)
    assert low == pytest.approx(1.33 - half)
    assert high == pytest.approx(1.33 + half)
    assert lot.cpk_interval(None, 30) == (None, None)
    assert lot.cpk_interval(21.9, 2) == (None, None)  # it was -8.45 to 52.2: none below 10 units
    assert lot.cpk_interval(1.33, 10) != (None, None)
    # coverage: lots of 50 units, N(0, 1) against limits ±4 (true Cpk 4/3)
    x = np.random.default_rng(3).standard_normal((2000, 50))
    covered = 0
    for sample in x:
        value = lot.cpk(sample, -4.0, 4.0)
        lo, hi = lot.cpk_interval(value, 50)
        assert lo is not None
        assert hi is not None
        covered += lo <= 4 / 3 <= hi
    assert covered / 2000 == pytest.approx(0.95, abs=0.02)
