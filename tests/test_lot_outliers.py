"""The lot report's outlier flags control the lot-wide false-alarm rate (core/outliers.py).

Simulated lots of good units: every figure N(0, 1) per unit, 12 figures (a six-pose lot: offsets,
gains, cross terms). "A unit 6σ off": its figure lies exactly 6 σ from the population mean."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import run
from tests.lotgen import write_lot
from tests.test_report_cli import LOT
from tumblecal_cli.core import outliers

FIGURES = 12
LOTS = 1000
SIZES = (8, 12, 20, 30, 40, 60, 100, 200)


def flagged_lots(rng: np.random.Generator, n: int, shift: float | None) -> tuple[float, float, float]:
    """(fraction of lots with any flag, fraction in which the planted unit is flagged, the power
    the report states for that unit)."""
    rule = outliers.OutlierRule(outliers.OUTLIER_ALPHA, FIGURES * n)
    x = rng.standard_normal((LOTS, FIGURES, n))
    if shift is not None:
        x[:, 0, 0] = shift
    flags, _ = rule.flags(x)
    return float(flags.any(axis=(1, 2)).mean()), float(flags[:, 0, 0].mean()), rule.power(n)


@pytest.mark.slow
@pytest.mark.parametrize("n", SIZES)
def test_at_most_one_lot_in_a_hundred_of_good_units_is_flagged(n: int) -> None:
    """From 8 units up (the issue asked at most 1 good lot in 20 of 8; the rule holds 1 in 200)."""
    rate, _, _ = flagged_lots(np.random.default_rng(100 + n), n, None)
    assert rate <= 0.01


@pytest.mark.slow
@pytest.mark.parametrize("n", SIZES)
def test_a_unit_6_sigma_off_is_caught_as_often_as_the_report_says(n: int) -> None:
    """Every lot of 8 units or more is judged (a 6σ unit in a lot of 30 went unnamed while the
    rule waited for 95 % power, at 46 units); the power the report states for the lot's size is
    the simulated one, and from ``detect_units`` on it is at least 95 %."""
    _, found, stated = flagged_lots(np.random.default_rng(200 + n), n, 6.0)
    assert found == pytest.approx(stated, abs=0.05)
    if n >= outliers.OutlierRule(outliers.OUTLIER_ALPHA, FIGURES * n).detect_units:
        assert found >= 0.95


def test_the_lot_size_for_95_percent_power() -> None:
    """Documented in docs/lot-report.md: 12 figures need 46 units at the default alpha, 6 need 36."""
    assert [outliers.smallest_lot(f) for f in (6, 12)] == [36, 46]
    assert [outliers.smallest_lot(12, a) for a in (0.01, 0.05)] == [36, 21]
    assert all(n < outliers.OutlierRule(0.005, 12 * n).detect_units for n in (8, 20, 30, 40, 45))
    assert all(n >= outliers.OutlierRule(0.005, 12 * n).detect_units for n in (46, 60, 100, 200))


def test_the_power_model_agrees_with_simulation() -> None:
    """detect_units is the smallest lot whose noncentral-t power against 6σ reaches 95 %; the
    simulated power there agrees with the model."""
    rule = outliers.OutlierRule(0.005, FIGURES * 46)
    least = rule.detect_units
    assert rule.power(least) >= 0.95 > rule.power(least - 1)
    x = np.random.default_rng(5).standard_normal((2000, least))
    x[:, 0] = 6.0
    flags, _ = rule.flags(x)
    assert float(flags[:, 0].mean()) == pytest.approx(rule.power(least), abs=0.015)


def test_two_units_off_in_one_figure_are_both_flagged() -> None:
    """The median/MAD screen keeps one far unit from hiding another (masking)."""
    x = np.random.default_rng(9).standard_normal((500, 60))
    x[:, 0], x[:, 1] = 7.0, -7.0
    flags, _ = outliers.OutlierRule(0.005, 60 * 12).flags(x)
    assert flags[:, 0].mean() >= 0.95
    assert flags[:, 1].mean() >= 0.95
    assert flags[:, 2:].any(axis=1).mean() <= 0.01


@pytest.mark.parametrize(
    ("p", "df", "expected"),
    [(0.05, 1, 12.706), (0.05, 6, 2.447), (0.01, 10, 3.169), (0.001, 30, 3.646), (0.05, 1000, 1.962)],
)
def test_t_quantile_matches_the_tables(p: float, df: float, expected: float) -> None:
    assert outliers.t_quantile(p, df) == pytest.approx(expected, abs=5e-4)


def test_the_cli_default_is_the_library_default() -> None:
    import inspect

    from tumblecal_cli.cli import report

    default = inspect.signature(report.report).parameters["outlier_alpha"].default
    assert default == outliers.OUTLIER_ALPHA == outliers.OutlierRule().alpha


@pytest.mark.parametrize("alpha", ["2", "0", "-0.1", "nan", "1"])
def test_outlier_alpha_out_of_range_is_one_line_and_exit_2(alpha: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "report", str(LOT), "--outlier-alpha", alpha)
    assert (code, out) == (2, "")
    assert err.startswith("error: --outlier-alpha must be a probability between 0 and 1")
    assert len([line for line in err.splitlines() if line.startswith("error")]) == 1
    assert "Traceback" not in err


def test_a_lot_of_eight_good_units_is_in_order(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The lot that had two units flagged (a 2.6σ offset, a cross term of pure noise) and exit 1:
    judged now, at a lot-wide false-alarm rate of 0.005, nothing is flagged, and the report says
    how weak a lot of 8 is against a unit 6σ off."""
    write_lot(tmp_path, n=8, seed=3)  # no unit planted below SN0013
    code, out, err = run(capsys, "report", str(tmp_path))
    assert code == 0, err
    assert "outliers: |t| > 10.2 vs the other units (false alarms 0.005 per lot, 96 unit-figures; a unit 6σ " in err
    assert "in a lot this size, caught 7% of the time)" in err
    assert {line.split(",")[10] for line in out.splitlines()[1:]} == {""}
    assert "lot: in order" in err


def test_a_unit_6_sigma_off_in_a_lot_of_30_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """30 units, one 6σ off on one offset: "outliers: not judged (30 units; 36 needed ...)", exit 0,
    the histogram showing it plainly. Named now, exit 1."""
    write_lot(tmp_path, n=30, seed=4)
    unit = tmp_path / "SN0005_20261121.json"
    doc = json.loads(unit.read_text())
    others = [json.loads(p.read_text())["offset"][1] for p in sorted(tmp_path.glob("*.json")) if p != unit]
    doc["offset"][1] = float(np.mean(others) + 6.0 * np.std(others, ddof=1))
    unit.write_text(json.dumps(doc))
    code, _out, err = run(capsys, "report", str(tmp_path))
    assert code == 1, err
    assert any(line.startswith("outlier: SN0005: offset.y ") for line in err.splitlines()), err
