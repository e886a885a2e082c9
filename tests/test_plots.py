"""The PNG figures of ``solve --plot`` and ``report --plot`` (tumblecal_cli/io/figures/plots.py).

Synthetic data with a known offset and matrix: the figures must be valid PNGs of the size asked
for, show the numbers they claim to show, be written atomically, and refuse bad input with an
InputError before any file is touched.
"""

from __future__ import annotations

import contextlib
import importlib.util
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.image import imread
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from numpy.typing import NDArray

from tests.conftest import imported, png_size
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.figures import plots
from tumblecal_cli.io.outputs import atomic_output

FloatArray = NDArray[np.float64]

OFFSET = np.array([0.02, -0.03, 0.05])
A = np.array([[1.01, 0.004, -0.006], [0.003, 0.98, 0.005], [-0.004, 0.002, 1.02]])  # gains 1.01/0.98/1.02
M = np.linalg.inv(A)
NOISE = 0.002


def directions(n: int, seed: int = 0) -> FloatArray:
    """``n`` unit vectors spread over the sphere."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    unit: FloatArray = v / np.linalg.norm(v, axis=1, keepdims=True)
    return unit


def pose_means(n: int, reference: float = 1.0) -> FloatArray:
    """Mean raw readings of ``n`` static poses: raw = A·(reference·u) + offset + noise."""
    noise = np.random.default_rng(1).normal(0.0, NOISE, size=(n, 3))
    means: FloatArray = (reference * directions(n)) @ A.T + OFFSET + noise
    return means


def turning(n: int, reference: float, *, plane: bool = False) -> FloatArray:
    """A magnetometer turned through all orientations (or in the xy plane only), noise-free."""
    if plane:
        theta = np.linspace(0.0, 6 * math.pi, n)
        u = np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], axis=1)
    else:
        u = directions(n, seed=2)
    raw: FloatArray = (reference * u) @ A.T + OFFSET
    return raw


def check_png(path: Path, width: int, height: int) -> None:
    """A valid PNG of ``width``×``height`` pixels that matplotlib decodes to that size."""
    assert png_size(path.read_bytes()) == (width, height)
    pixels = imread(path)
    assert pixels.shape[:2] == (height, width)
    assert pixels.std() > 0.05  # something was drawn, not a blank page


def xdata(line: Line2D) -> FloatArray:
    return np.asarray(line.get_xdata(), dtype=np.float64)


def ydata(line: Line2D) -> FloatArray:
    return np.asarray(line.get_ydata(), dtype=np.float64)


def heights(ax: Axes) -> list[float]:
    """The heights of an axes' bars, in drawing order."""
    return [patch.get_height() for patch in ax.patches if isinstance(patch, Rectangle)]


def distance_to_polyline(points: FloatArray, curve: FloatArray) -> FloatArray:
    """Each point's distance to the nearest segment of a polyline."""
    start, step = curve[:-1], np.diff(curve, axis=0)
    t = np.einsum("psk,sk->ps", points[:, None, :] - start[None], step) / np.einsum("sk,sk->s", step, step)
    foot = start[None] + np.clip(t, 0.0, 1.0)[..., None] * step[None]
    distance: FloatArray = np.linalg.norm(points[:, None, :] - foot, axis=2).min(axis=1)
    return distance


def small_figure(path: str) -> None:
    """A small figure of one histogram (400×340 pixels), for the tests of how figures are written."""
    plots.lot_figure(path, [plots.Histogram("gain", np.array([0.99, 1.0, 1.01]), 0.97, 1.03)])


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """The figures the plot functions would write, kept instead of rendered (fast, inspectable)."""
    kept: list[Figure] = []
    monkeypatch.setattr(plots, "write_png", lambda fig, path: kept.append(fig))
    return kept


# --- PNG output -------------------------------------------------------------------------------


@pytest.mark.slow
def test_rotation_figure_is_a_png_of_the_right_size(tmp_path: Path) -> None:
    path = tmp_path / "rotation.png"
    plots.rotation_figure(
        str(path), turning(1500, 50.0), plots.PlottedCorrection(OFFSET, M, 50.0, units="uT"), title="magnetometer"
    )
    check_png(path, 1200, 1050)


@pytest.mark.slow
def test_lot_figure_is_a_png_of_the_right_size(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    histograms = [plots.Histogram(f"offset.{a}", rng.normal(0.02, 0.01, 40), -0.05, 0.05, "g") for a in "xyz"]
    histograms += [plots.Histogram(f"gain.{a}", rng.normal(1.0, 0.01, 40), 0.97, None) for a in "xyz"]
    histograms += [
        plots.Histogram("one unit", np.array([0.3]), None, None),
        plots.Histogram("identical", np.full(10, 2.5), 2.0, 3.0, "counts"),
        plots.Histogram("identical, no limits", np.zeros(5), None, None),
    ]
    path = tmp_path / "lot.png"
    plots.lot_figure(str(path), histograms, title="lot 42")
    check_png(path, 1420, 860)  # 9 panels: 4 columns, 3 rows


@pytest.mark.slow
def test_same_call_same_bytes(tmp_path: Path) -> None:
    first, second = tmp_path / "a.png", tmp_path / "b.png"
    for path in (first, second):
        small_figure(str(path))
    assert first.read_bytes() == second.read_bytes()
    assert b"Software" not in first.read_bytes()


@pytest.mark.slow
def test_dash_writes_the_png_to_stdout(capsysbinary: pytest.CaptureFixture[bytes]) -> None:
    small_figure("-")
    out = capsysbinary.readouterr().out
    assert png_size(out) == (400, 340)


# --- what the figures show ---------------------------------------------------------------------


def test_rotation_figure_ellipse_lies_on_a_plane_capture(figures: list[Figure]) -> None:
    raw = turning(20000, 50.0, plane=True)
    plots.rotation_figure("unused.png", raw, plots.PlottedCorrection(OFFSET, M, 50.0, units="uT"))
    (fig,) = figures
    assert len(fig.axes) == 7  # three planes raw and corrected, and the residuals
    assert all(ax.get_aspect() == 1.0 for ax in fig.axes[:6])
    xy_raw, xy_corrected = fig.axes[0], fig.axes[1]
    samples, _outline, ellipse, _offset = xy_raw.get_lines()
    shown = np.column_stack([xdata(samples), ydata(samples)])
    assert len(shown) == plots.MAX_POINTS  # subsampled
    curve = np.column_stack([xdata(ellipse), ydata(ellipse)])
    assert distance_to_polyline(shown[::5], curve).max() < 0.01  # noise-free, radius 50: on the curve
    dots, circle, _origin = xy_corrected.get_lines()
    np.testing.assert_allclose(np.hypot(xdata(dots), ydata(dots)), 50.0, rtol=1e-9)
    np.testing.assert_allclose(np.hypot(xdata(circle), ydata(circle)), 50.0)


def test_rotation_figure_of_a_one_plane_capture_draws_that_plane_at_its_own_radius(figures: list[Figure]) -> None:
    """2-D min/max: turned about z with a 60° dip, the xy part of a 50 uT field is 25 uT; the
    figure shows the xy plane only, against a 25 uT circle (not the whole field's 50)."""
    n = 4000
    heading = np.linspace(0.0, 4 * math.pi, n)
    field = 50.0 * np.stack([0.5 * np.cos(heading), 0.5 * np.sin(heading), np.full(n, math.sqrt(0.75))], axis=1)
    offset = np.array([12.0, -7.0, 0.0])
    plots.rotation_figure(
        "unused.png", field + offset, plots.PlottedCorrection(offset, np.eye(3), 50.0, units="uT"), plane="xy"
    )
    (fig,) = figures
    assert len(fig.axes) == 3
    raw_axes, corrected_axes, residuals = fig.axes
    dots, _zero = residuals.get_lines()
    np.testing.assert_allclose(ydata(dots), 0.0, atol=1e-9)  # the in-plane norm is the 25 uT circle's
    assert "xy plane" in raw_axes.get_title()
    _dots, circle, _origin = corrected_axes.get_lines()
    np.testing.assert_allclose(np.hypot(xdata(circle), ydata(circle)), 25.0, rtol=1e-9)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "circle of radius 25 uT (the field's part in the xy plane)" in labels


def test_rotation_figure_residuals_are_in_percent_with_the_limit(figures: list[Figure]) -> None:
    """The residual of each sample after calibration, on its own axes in % of the reference (a
    1 % error is invisible on the circle of radius 50), and ±the residual limit dashed."""
    raw = turning(3000, 50.0)
    scale = 1.0 + 0.01 * np.sin(np.arange(3000) / 50.0)  # the norm wanders by ±1 %
    corrupted = (raw - OFFSET) * scale[:, None] + OFFSET
    plots.rotation_figure("unused.png", corrupted, plots.PlottedCorrection(OFFSET, M, 50.0, units="uT"), limit=0.75)
    (fig,) = figures
    residuals = fig.axes[6]
    dots = residuals.get_lines()[1]
    shown = ydata(dots)
    assert len(shown) == 3000
    np.testing.assert_allclose(shown, (scale - 1.0) * 100.0, atol=1e-9)
    limits = sorted(float(ydata(line)[0]) for line in residuals.get_lines()[2:])
    assert limits == pytest.approx([-1.5, 1.5])  # 0.75 uT of 50: 1.5 %
    low, high = residuals.get_ylim()
    assert low < min(shown.min(), -1.5)
    assert high > max(shown.max(), 1.5)
    assert residuals.get_ylabel() == "residual (% of reference)"


@pytest.mark.slow
def test_rotation_figure_outline_bounds_a_sphere_capture(figures: list[Figure]) -> None:
    plots.rotation_figure("unused.png", turning(3000, 1.0), plots.PlottedCorrection(OFFSET, M, 1.0))
    (fig,) = figures
    for ax in fig.axes[0:6:2]:  # top row: raw
        samples, outline, _ellipse, _offset = ax.get_lines()
        points = np.column_stack([xdata(samples), ydata(samples)])
        rim = np.column_stack([xdata(outline), ydata(outline)])
        centre = rim.mean(axis=0)
        reach = np.max(np.linalg.norm(points - centre, axis=1))
        assert reach <= np.max(np.linalg.norm(rim - centre, axis=1)) + 1e-9
        assert reach > 0.99 * np.min(np.linalg.norm(rim - centre, axis=1))


def test_lot_figure_without_limits_has_no_limit_legend(figures: list[Figure]) -> None:
    plots.lot_figure("unused.png", [plots.Histogram("offset.x", np.array([0.01, 0.02, 0.015]), None, None)])
    (fig,) = figures
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["mean"]


def test_lot_figure_draws_limits_mean_and_counts(figures: list[Figure]) -> None:
    values = np.array([0.96, 0.99, 1.0, 1.01, 1.05])
    plots.lot_figure(
        "unused.png",
        [plots.Histogram("gain.x", values, 0.97, 1.03, "raw/g"), plots.Histogram("single", np.array([7.0]), None, 8.0)],
    )
    (fig,) = figures
    gain, single = fig.axes
    assert gain.get_title() == "gain.x (n=5, 2 outside)"
    assert single.get_title() == "single (n=1)"
    mean, lower, upper = gain.get_lines()
    assert xdata(mean)[0] == pytest.approx(values.mean())
    assert (xdata(lower)[0], xdata(upper)[0]) == (0.97, 1.03)
    assert lower.get_linestyle() == "--"
    assert gain.get_xlabel() == "raw/g"
    left, right = single.get_xlim()
    assert left < 7.0
    assert right > 8.0  # widened to show the limit
    assert sum(heights(single)) == 1


@pytest.mark.slow
def test_lot_figure_twenty_parameters_in_four_columns(figures: list[Figure]) -> None:
    rng = np.random.default_rng(4)
    plots.lot_figure("unused.png", [plots.Histogram(f"p{i}", rng.normal(i, 1, 50), i - 3, i + 3) for i in range(20)])
    (fig,) = figures
    assert len(fig.axes) == 20
    assert fig.get_size_inches()[0] == pytest.approx(3.4 * 4 + 0.6)


# --- bad input, atomic writes -------------------------------------------------------------------

BAD_INPUTS: list[tuple[str, Callable[[str], None], str]] = [
    (
        "rotation-nan",
        lambda p: plots.rotation_figure(p, np.full((10, 3), np.nan), plots.PlottedCorrection(OFFSET, M, 1.0)),
        "raw samples has 30 of 30 values that are not finite",
    ),
    (
        "rotation-singular",
        lambda p: plots.rotation_figure(p, turning(10, 1.0), plots.PlottedCorrection(OFFSET, np.zeros((3, 3)), 1.0)),
        "the calibration matrix is singular",
    ),
    (
        "rotation-reference",
        lambda p: plots.rotation_figure(p, turning(10, 1.0), plots.PlottedCorrection(OFFSET, M, 0.0)),
        "reference must be positive",
    ),
    (
        "rotation-empty",
        lambda p: plots.rotation_figure(p, np.empty((0, 3)), plots.PlottedCorrection(OFFSET, M, 1.0)),
        "no samples to plot",
    ),
    ("lot-empty", lambda p: plots.lot_figure(p, []), "no parameters to plot"),
    (
        "lot-nan",
        lambda p: plots.lot_figure(p, [plots.Histogram("noise", np.array([np.nan, np.nan]), None, None)]),
        "values of noise has 2 of 2 values that are not finite",
    ),
    (
        "lot-shape",
        lambda p: plots.lot_figure(p, [plots.Histogram("gain", np.ones((2, 3)), None, None)]),
        "values of gain has shape 2×3, expected n",
    ),
    (
        "lot-no-values",
        lambda p: plots.lot_figure(p, [plots.Histogram("gain", np.array([]), None, None)]),
        "no values of gain to plot",
    ),
    (
        "lot-limits",
        lambda p: plots.lot_figure(p, [plots.Histogram("gain", np.ones(3), 1.1, 0.9)]),
        "gain: lower limit 1.1 is above upper limit 0.9",
    ),
    (
        "lot-inf-limit",
        lambda p: plots.lot_figure(p, [plots.Histogram("gain", np.ones(3), None, math.inf)]),
        "gain limit is not finite",
    ),
]


@pytest.fixture(scope="module")
def good_png(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """A good figure, rendered once for the module."""
    path = tmp_path_factory.mktemp("good") / "figure.png"
    small_figure(str(path))
    return path.read_bytes()


@pytest.fixture
def good_file(tmp_path: Path, good_png: bytes) -> Path:
    """A folder holding one good figure, to be left alone by every failed write."""
    path = tmp_path / "figure.png"
    path.write_bytes(good_png)
    return path


@pytest.mark.slow
@pytest.mark.parametrize(("call", "message"), [(c, m) for _, c, m in BAD_INPUTS], ids=[i for i, _, _ in BAD_INPUTS])
def test_bad_input_is_an_input_error_and_leaves_the_old_file(
    good_file: Path, call: Callable[[str], None], message: str
) -> None:
    before = good_file.read_bytes()
    with pytest.raises(InputError, match=message):
        call(str(good_file))
    assert good_file.read_bytes() == before
    assert [p.name for p in good_file.parent.iterdir()] == [good_file.name]


def test_failed_render_leaves_the_old_file(good_file: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("renderer failed")

    before = good_file.read_bytes()
    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(RuntimeError, match="renderer failed"):
        small_figure(str(good_file))
    assert good_file.read_bytes() == before
    assert [p.name for p in good_file.parent.iterdir()] == [good_file.name]


@pytest.mark.slow
def test_failed_write_leaves_the_old_file(good_file: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The disk fills half-way through the PNG: the temporary file goes, the old figure stays."""

    class HalfWay:
        def __init__(self, stream: IO[bytes]) -> None:
            self.stream = stream

        def write(self, data: bytes) -> int:
            self.stream.write(data[: len(data) // 2])
            raise OSError(28, "No space left on device")

    @contextlib.contextmanager
    def failing(path: str) -> Iterator[HalfWay]:
        with atomic_output(path) as stream:
            yield HalfWay(stream)

    before = good_file.read_bytes()
    monkeypatch.setattr(plots, "atomic_output", failing)
    with pytest.raises(InputError, match=f"{good_file}: cannot write: No space left on device"):
        small_figure(str(good_file))
    assert good_file.read_bytes() == before
    assert [p.name for p in good_file.parent.iterdir()] == [good_file.name]


@pytest.mark.slow
def test_missing_output_folder_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="the output folder does not exist"):
        small_figure(str(tmp_path / "nowhere" / "f.png"))


# --- the optional extra -------------------------------------------------------------------------


def test_require_names_the_extra_when_matplotlib_is_missing(monkeypatch: pytest.MonkeyPatch) -> None:
    plots.require()  # installed in the dev venv
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, package=None: None)
    with pytest.raises(InputError, match="--plot needs matplotlib, which is not installed") as err:
        plots.require()
    assert err.value.hint == "pip install 'tumblecal[plot]'"


def test_importing_plots_does_not_import_matplotlib() -> None:
    """The --plot check (require) runs before any work: matplotlib is imported when a figure is
    drawn. (numpy is imported at the top, as everywhere in io: every command that plots uses it.)"""
    body = "import tumblecal_cli.io.figures.plots\ntumblecal_cli.io.figures.plots.require()"
    assert imported(body, ("matplotlib", "PIL")) == []
