"""The figures that judge a fit (tumblecal_cli/io/figures/fitplots.py): ``solve --plot`` of static poses,
``verify --plot`` and ``segment --plot``.

Synthetic poses with a known offset and matrix check the numbers each panel shows; the real logs
and tables of tests/data (imu_tk's Xsens log, imucal's Ferraris session, Hassan's tables) check
that the residuals are drawn on a scale where they are visible, with the limits in force, and
that bad paths are refused before any work.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.container import ErrorbarContainer
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from tests.conftest import png_size, run
from tests.test_plots import OFFSET, A, M, directions, xdata, ydata
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.figures import fitplots, plots

FloatArray = np.ndarray
ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
XSENS_LOG = DATA / "logs" / "xsens_acc.txt.gz"
SESSION_LOG = DATA / "logs" / "imucal_ferraris_session.csv.gz"
HASSAN = DATA / "hassan_gnls"
SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
AXIS = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """The figures the plot functions would write, kept instead of rendered (fast, inspectable)."""
    kept: list[Figure] = []
    monkeypatch.setattr(fitplots, "write_png", lambda fig, path: kept.append(fig))
    monkeypatch.setattr(plots, "write_png", lambda fig, path: kept.append(fig))
    return kept


def limit_values(ax: Axes) -> list[float]:
    """The heights of an axes' horizontal red dashed lines (the limits drawn), sorted."""
    return sorted(
        float(ydata(line)[0])
        for line in ax.get_lines()
        if line.get_linestyle() == "--" and len(set(ydata(line).tolist())) == 1 and len(ydata(line)) == 2
    )


def means_of(ax: Axes) -> FloatArray:
    """The points of an axes' error bars (the pose or capture means)."""
    (bars,) = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    line = bars.lines[0]
    assert isinstance(line, Line2D)
    return ydata(line)


def contains(ax: Axes, values: FloatArray) -> bool:
    low, high = ax.get_ylim()
    return bool(low <= float(np.min(values)) and float(np.max(values)) <= high)


def six_poses(rng: np.random.Generator, noise: float = 0.002, n: int = 400) -> list[fitplots.PoseData]:
    """Six faces in g: raw = A·u + offset + noise, each with a tilt of 0.3° to 1.4° as read."""
    out = []
    for k, face in enumerate(SIX):
        u = np.asarray(AXIS[face], dtype=np.float64)
        samples = u @ A.T + OFFSET + rng.normal(0.0, noise, size=(n, 3))
        out.append(fitplots.PoseData(face, samples.mean(axis=0), samples, face, 0.3 + 0.2 * k))
    return out


# --- solve --plot of static poses ---------------------------------------------------------------


def test_six_poses_residuals_in_mg_with_spread_uncertainty_limit_and_tilt(figures: list[Figure]) -> None:
    rng = np.random.default_rng(5)
    poses = six_poses(rng)
    fitted = plots.PlottedCorrection(OFFSET, np.diag(1 / np.diag(A)), 1.0, "g")  # gains only: the cross terms are left
    bounds = fitplots.Bounds(residual=0.004, tolerance_deg=1.0)
    before = fitplots.Before(np.zeros(3), 1.0, "raw")
    fitplots.poses_figure("unused.png", poses, fitted, bounds, before, title="six")
    (fig,) = figures
    after, raw, tilt = fig.axes
    corrected = [
        np.linalg.norm((p.samples - OFFSET) @ fitted.matrix.T, axis=1) - 1.0 for p in poses if p.samples is not None
    ]
    expected = np.array([np.linalg.norm(fitted.matrix @ (p.mean - OFFSET)) - 1.0 for p in poses]) * 1000.0
    np.testing.assert_allclose(means_of(after), expected)  # in mg
    assert after.get_ylabel() == "residual (mg)"
    assert limit_values(after) == pytest.approx([-4.0, 4.0])  # the residual limit, 0.004 g
    whiskers = np.concatenate([np.percentile(c * 1000.0, [5.0, 95.0]) for c in corrected])
    assert contains(after, np.concatenate([expected, whiskers, [-4.0, 4.0]]))
    sigma = np.array([np.std(c, ddof=1) / math.sqrt(c.size) for c in corrected]) * 1000.0
    (bars,) = [c for c in after.containers if isinstance(c, ErrorbarContainer)]
    segments = bars.lines[2][0].get_segments()  # the vertical error bars: mean ± 1σ
    np.testing.assert_allclose([s[1][1] - s[0][1] for s in segments], 2 * sigma, rtol=1e-9)
    assert [t.get_text() for t in after.get_xticklabels()] == list(SIX)
    # before, on its own axes: |raw| − 1 g, tens of mg, not on the after axes' scale
    shown = ydata(raw.get_lines()[1])
    np.testing.assert_allclose(shown, (np.linalg.norm([p.mean for p in poses], axis=1) - 1.0) * 1000.0)
    assert np.max(np.abs(shown)) > 15.0
    assert "before calibration" in raw.get_title()
    # the tilt of each pose from its face, as read, against the fixture tolerance
    assert [r.get_height() for r in tilt.patches if isinstance(r, Rectangle)] == pytest.approx(
        [0.3 + 0.2 * k for k in range(6)]
    )
    (tolerance,) = [line for line in tilt.get_lines() if ydata(line).tolist() == [1.0, 1.0]]
    assert "fixture tolerance 1°" in str(tolerance.get_label())


def test_sphere_fit_shows_the_calibrated_poses_on_the_unit_sphere(figures: list[Figure]) -> None:
    """Poses without faces (sphere, least squares): the calibrated poses' directions on the
    unit sphere, coloured by residual in mg; no tilt panel."""
    rng = np.random.default_rng(6)
    u = directions(20, seed=3)
    gain = 2500.0  # unsigned counts around 32768, as the Xsens log
    means = (u @ A.T * gain) + OFFSET * gain + 32768.0 + rng.normal(0.0, 0.5, size=(20, 3))
    poses = [fitplots.PoseData(f"block {k + 1}", m) for k, m in enumerate(means)]
    fitted = plots.PlottedCorrection(OFFSET * gain + 32768.0, M / gain, 1.0, "g")
    before = fitplots.Before(OFFSET * gain + 32768.0, gain, "(raw − fitted offset) ÷ mean gain")
    fitplots.poses_figure("unused.png", poses, fitted, fitplots.Bounds(), before)
    (fig,) = figures
    after, _raw, sphere, colourbar = fig.axes
    assert sphere.name == "3d"
    (points,) = sphere.collections[1:2]
    xyz = np.column_stack(points._offsets3d)  # type: ignore[attr-defined]
    np.testing.assert_allclose(np.linalg.norm(xyz, axis=1), 1.0)
    residual = (np.linalg.norm((means - fitted.offset) @ fitted.matrix.T, axis=1) - 1.0) * 1000.0
    np.testing.assert_allclose(np.asarray(points.get_array()), residual)
    assert colourbar.get_ylabel() == "residual (mg)"
    assert after.get_xlabel() == "block"
    assert [t.get_text() for t in after.get_xticklabels()] == [str(k + 1) for k in range(20)]
    assert limit_values(after) == []  # no limit given, none drawn


def test_poses_figure_refuses_bad_input(tmp_path: Path) -> None:
    path = tmp_path / "f.png"
    fitted = plots.PlottedCorrection(OFFSET, M, 1.0)
    before = fitplots.Before(np.zeros(3), 1.0, "raw")
    with pytest.raises(InputError, match="no poses to plot"):
        fitplots.poses_figure(str(path), [], fitted, fitplots.Bounds(), before)
    with pytest.raises(InputError, match="nominal gain must be positive"):
        fitplots.poses_figure(str(path), six_poses(np.random.default_rng(1)), fitted, fitplots.Bounds(),
                              fitplots.Before(np.zeros(3), 0.0, "raw"))  # fmt: skip
    nan = [fitplots.PoseData("a", np.full(3, np.nan))]
    with pytest.raises(InputError, match="pose means has 3 of 3 values that are not finite"):
        fitplots.poses_figure(str(path), nan, fitted, fitplots.Bounds(), before)
    assert not path.exists()


def test_scale_is_mg_for_an_accelerometer_and_percent_otherwise() -> None:
    assert fitplots.Scale.of("g", 1.0) == fitplots.Scale(1000.0, "mg")
    assert fitplots.Scale.of("m/s^2", 9.81).factor == pytest.approx(1000.0 / 9.81)  # 1 g is the reference
    assert fitplots.Scale.of(None, 16384.0).unit == "mg"  # counts at 16384 LSB/g
    assert fitplots.Scale.of("uT", 50.0, "magnetometer") == fitplots.Scale(2.0, "% of reference")
    assert fitplots.Scale.of("dps", 0.0, "gyroscope") == fitplots.Scale(1.0, "dps")


@pytest.mark.slow
def test_xsens_log_sphere_plot_shows_the_residuals_not_the_adc_offset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], figures: list[Figure]
) -> None:
    """imu_tk's Xsens log is in unsigned counts around 33000: drawn against 0, "before" read
    13 g and squashed the calibrated points onto a line. Now the residuals are in mg on their
    own axes, "before" is the reading less the fitted offset, and the 38 blocks lie on the
    unit sphere."""
    code, _, err = run(capsys, "solve", "--log", XSENS_LOG, "--no-header", "-o", tmp_path / "c.json",
                       "--plot", tmp_path / "x.png", "-q")  # fmt: skip
    assert code == 0, err
    (fig,) = figures
    after, raw, sphere, _colourbar = fig.axes
    residual = means_of(after)
    assert len(residual) == 38
    assert float(np.max(np.abs(residual))) < 1.0  # measured: 0.24 mg
    low, high = after.get_ylim()
    assert -5.0 < low < float(np.min(residual))
    assert float(np.max(residual)) < high < 5.0
    before = ydata(raw.get_lines()[1])
    assert 1.0 < float(np.max(np.abs(before))) < 50.0  # measured: 12 mg; against 0 it was 13 g
    assert "fitted offset" in raw.get_title()
    xyz = np.column_stack(sphere.collections[1]._offsets3d)  # type: ignore[attr-defined]
    np.testing.assert_allclose(np.linalg.norm(xyz, axis=1), 1.0)


@pytest.mark.slow
def test_imucal_six_faces_plot_in_mg_with_the_residual_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], figures: list[Figure]
) -> None:
    """imucal's session in m/s² against 9.81: residuals in mg (1 g is the reference), the
    limit of a limits file drawn, each face's tilt against the fixture tolerance."""
    limits = tmp_path / "limits.yaml"
    limits.write_text("residual: 0.05\n")  # m/s^2: 5.1 mg
    code, _, err = run(capsys, "solve", "--log", SESSION_LOG, "--rate", "102.4", "--reference", "9.81",
                       "--limits", limits, "-o", tmp_path / "c.json", "--plot", tmp_path / "x.png", "-q")  # fmt: skip
    assert code == 0, err
    (fig,) = figures
    after, _raw, tilt = fig.axes
    assert after.get_ylabel() == "residual (mg)"
    assert limit_values(after) == pytest.approx([-0.05 / 9.81 * 1000.0, 0.05 / 9.81 * 1000.0])
    assert sorted(t.get_text().split()[0] for t in after.get_xticklabels()) == sorted(SIX)
    angles = [r.get_height() for r in tilt.patches if isinstance(r, Rectangle)]
    assert len(angles) == 6
    assert all(0.0 < a < 3.0 for a in angles)
    assert any(ydata(line).tolist() == [1.0, 1.0] for line in tilt.get_lines())


# --- verify --plot --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def hassan_cal(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A sphere calibration from Hassan's 24-orientation table."""
    from tests.conftest import tumblecal

    cal = tmp_path_factory.mktemp("hassan") / "cal.json"
    r = tumblecal("solve", "-p", HASSAN / "orient24.csv", "-o", cal, "-q")
    assert r.code == 0, r.err
    return cal


def test_verify_plot_marks_the_rows_outside_the_limit(
    hassan_cal: Path, capsys: pytest.CaptureFixture[str], figures: list[Figure], tmp_path: Path
) -> None:
    code, _, err = run(capsys, "verify", "--cal", hassan_cal, HASSAN / "orient31.csv", "--max-norm-error", "0.003",
                       "--plot", tmp_path / "v.png", "-q")  # fmt: skip
    assert code == 1, err
    (fig,) = figures
    after, before = fig.axes
    assert limit_values(after) == pytest.approx([-3.0, 3.0])
    errorbars = [c for c in after.containers if isinstance(c, ErrorbarContainer)]
    ok, failed = (ydata(c.lines[0]) for c in errorbars)
    assert len(ok) + len(failed) == 31
    assert len(failed) == 1
    assert abs(failed[0]) > 3.0
    assert np.all(np.abs(ok) <= 3.0)
    assert contains(after, np.concatenate([ok, failed, [-3.0, 3.0]]))
    assert after.get_xlabel() == "orient31.csv row"
    assert [t.get_text() for t in after.get_xticklabels()] == [str(k) for k in range(31)]
    assert "before calibration" in before.get_title()


@pytest.mark.slow
def test_verify_plot_writes_a_png_on_exit_1_and_nothing_on_bad_paths(
    hassan_cal: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    png = tmp_path / "v.png"
    args: list[str | Path] = ["verify", "--cal", hassan_cal, HASSAN / "orient31.csv", "--max-norm-error", "0.003"]
    code, _, err = run(capsys, *args, "--plot", png)
    assert code == 1
    assert f"wrote {png}" in err
    width, height = png_size(png.read_bytes())
    assert width > height > 300
    folder = tmp_path / "folder.png"
    folder.mkdir()
    for bad, message in ((folder, "is a folder: --plot takes a file name"),
                         (tmp_path / "no" / "v.png", "the output folder does not exist"),
                         (tmp_path / "v.pdf", "--plot writes a PNG image")):  # fmt: skip
        code, out, err = run(capsys, *args, "--plot", bad)
        assert (code, out) == (2, ""), err
        assert message in err
        assert len(err.strip().splitlines()) <= 2  # the error, and a hint where one helps
        assert not Path(bad).is_file()
    code, _, err = run(capsys, *args, "--json", "--plot", "-")
    assert code == 2
    assert "--plot - would share stdout with the data" in err
    code, _, err = run(capsys, "verify", "--cal", hassan_cal, "--log", HASSAN / "orient31.csv", "--accel-cal",
                       hassan_cal, "--plot", png)  # fmt: skip
    assert code == 2
    assert "--plot draws the errors of static captures, not of a --log of hand turns" in err


def test_verify_plot_not_written_when_a_capture_moves(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cal = tmp_path / "cal.json"
    code, _, err = run(capsys, "solve", "-p", *(str(ROOT / "sample_data" / f"{f}.csv") for f in "xyz"), "-o", cal, "-q")
    assert code == 0, err
    moving = tmp_path / "moving.csv"
    rng = np.random.default_rng(2)
    readings = rng.normal(0.0, 0.05, size=(200, 3)) + np.array([0.0, 0.0, 1.0])  # +z, shaking
    rows = "\n".join(",".join(f"{v:.5f}" for v in r) for r in readings)
    moving.write_text("x,y,z\n" + rows + "\n")
    png = tmp_path / "v.png"
    code, _, err = run(capsys, "verify", "--cal", cal, moving, "--no-rows-are-poses", "--plot", png)
    assert code == 3, err
    assert "not a static capture" in err
    assert not png.exists()


# --- segment --plot -------------------------------------------------------------------------------


@pytest.mark.slow
def test_segment_plot_shades_and_labels_each_block(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], figures: list[Figure]
) -> None:
    """imucal's session: 13 still blocks, each shaded on both axes and labelled with its face,
    the files they go to under the faces, the rolling standard deviation with the threshold."""
    out = tmp_path / "poses"
    code, _index, err = run(
        capsys, "segment", SESSION_LOG, "--rate", "102.4", "--plot", tmp_path / "s.png", "-d", out, "-q"
    )
    assert code == 0, err
    (fig,) = figures
    top, bottom = fig.axes
    spans = [p for p in top.patches if isinstance(p, Rectangle) or type(p).__name__ == "Polygon"]
    assert len(spans) == 13
    texts = [t.get_text() for t in top.texts]
    assert sorted(set(texts) & set(SIX)) == sorted(SIX)
    assert {"xp", "xn", "yp", "yn", "zp", "zn"} <= set(texts)  # the six face files, under their blocks
    (threshold,) = [line for line in bottom.get_lines() if line.get_linestyle() == "--"]
    assert float(ydata(threshold)[0]) == pytest.approx(0.0683, rel=0.01)  # measured
    assert bottom.get_yscale() == "log"
    low, high = top.get_xlim()
    assert low == 0.0
    assert high == pytest.approx(10412 / 102.4, rel=0.01)
    values = np.concatenate([ydata(line) for line in top.get_lines()])
    assert contains(top, values)
    assert (out / "xp.csv").exists()  # and the blocks are written as without --plot
    assert [h.get_label() for h in fig.legends[0].legend_handles if h is not None][:3] == ["x", "y", "z"]


@pytest.mark.slow
def test_segment_plot_writes_a_png_and_refuses_bad_paths(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "s.png"
    code, index, err = run(capsys, "segment", SESSION_LOG, "--rate", "102.4", "--plot", png)
    assert code == 0, err
    assert index.startswith("block,")  # the index still goes to stdout
    assert png_size(png.read_bytes()) == (1400, 700)
    out = tmp_path / "poses"
    folder = tmp_path / "folder.png"
    folder.mkdir()
    for bad, message in ((folder, "is a folder: --plot takes a file name"),
                         (tmp_path / "no" / "s.png", "the output folder does not exist"),
                         ("-", "--plot - would share stdout with the data")):  # fmt: skip
        where: list[str | Path] = ["-d", out] if bad != "-" else []
        code, stdout, err = run(capsys, "segment", SESSION_LOG, "--plot", bad, *where)
        assert (code, stdout) == (2, ""), err
        assert message in err
        assert not out.exists()  # refused before any work


def test_envelope_keeps_a_spike_of_a_long_log() -> None:
    t = np.arange(100_000, dtype=np.float64)
    y = np.zeros(100_000)
    y[54_321] = 7.0
    tx, ty = fitplots._envelope(t, y)
    assert len(ty) == 2 * fitplots.LOG_COLUMNS
    assert float(ty.max()) == 7.0
    assert float(tx[0]) == 0.0
    assert np.all(np.diff(tx) >= 0)


def test_segment_figure_of_a_log_without_time(figures: list[Figure]) -> None:
    """No time column and no rate: the x axis counts samples."""
    from tumblecal_cli.core import blocks

    rng = np.random.default_rng(8)
    still = [np.asarray(AXIS[f], dtype=np.float64) + rng.normal(0, 0.001, (300, 3)) for f in ("+z", "+x")]
    move = rng.normal(0.0, 0.5, (100, 3))
    data = np.concatenate([still[0], move, still[1]])
    seg = blocks.detect(data, None, None)
    fitplots.segment_figure("unused.png", data, None, seg, {})
    (fig,) = figures
    top, bottom = fig.axes
    assert bottom.get_xlabel() == "sample"
    faces = [t.get_text() for t in top.texts]
    assert faces == ["+z", "+x"]
    assert xdata(top.get_lines()[0]).max() == len(data) - 1


def test_an_exact_fit_says_so_and_a_gyroscope_has_no_sphere(figures: list[Figure]) -> None:
    """Three poses, three gains and three offsets: the residuals are 0 by construction, which the
    title says (only verify judges such a fit). A gyroscope at rest (reference 0) has no
    direction: no tilt and no sphere panel, "before" takes the row."""
    rng = np.random.default_rng(9)
    gains = np.array([1.01, 0.98, 1.02])
    poses = []
    for face in ("+x", "+y", "+z"):
        mean = OFFSET + gains * np.asarray(AXIS[face], dtype=np.float64)  # no cross terms: three poses fit exactly
        samples = mean + rng.normal(0.0, 0.002, (400, 3))
        poses.append(fitplots.PoseData(face, mean, samples - samples.mean(axis=0) + mean, face, 0.5))
    exact = plots.PlottedCorrection(OFFSET, np.diag(1 / gains), 1.0, "g")
    before = fitplots.Before(np.zeros(3), 1.0, "raw")
    fitplots.poses_figure("unused.png", poses, exact, fitplots.Bounds(), before)
    still = [fitplots.PoseData("still.csv", np.array([3.0, -2.0, 5.0]), rng.normal([3.0, -2.0, 5.0], 0.1, (500, 3)))]
    gyro = plots.PlottedCorrection(np.array([3.0, -2.0, 5.0]), np.eye(3), 0.0, "dps")
    fitplots.poses_figure("unused.png", still, gyro, fitplots.Bounds(), before, sensor="gyroscope")
    three, gyroscope = figures
    assert "0 by construction" in three.axes[0].get_title()
    assert np.max(np.abs(means_of(three.axes[0]))) < 1e-9
    after, raw = gyroscope.axes
    assert after.get_title().startswith("after calibration: |corrected| per pose")
    assert after.get_ylabel() == "residual (dps)"
    spec = raw.get_subplotspec()
    assert spec is not None
    assert spec.colspan == range(2)  # the whole row
    assert "0 by construction" in after.get_title()  # the bias is the mean: an exact fit too


@pytest.mark.slow
def test_segment_from_python_draws_the_plot(tmp_path: Path) -> None:
    import tumblecal_cli as tumblecal

    png = tmp_path / "blocks.png"
    done = tumblecal.segment(str(SESSION_LOG), rate=102.4, plot=str(png))
    assert len(done.blocks.seg.kept) == 13
    width, height = png_size(png.read_bytes())
    assert (width, height) == (1400, 700)
