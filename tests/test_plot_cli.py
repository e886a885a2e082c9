"""solve --plot and report --plot from the command line: a valid PNG when asked, nothing when the
run fails, matplotlib imported only when a plot is asked for."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import imported, png_size, run, unnamed
from tests.test_solvers_cli import FIELD, magnetometer, sphere_directions, write_mag

ROOT = Path(__file__).resolve().parent.parent
SIX = [str(ROOT / "sample_data" / "imucal" / f"{f}.csv") for f in ("xp", "xn", "yp", "yn", "zp", "zn")]
THREE = [str(ROOT / "sample_data" / f"{f}.csv") for f in ("x", "y", "z")]
LOT = ROOT / "sample_data" / "lot"


def drawn_png_size(path: Path) -> tuple[int, int]:
    """Width and height of a valid PNG (signature, then the IHDR chunk) that decodes to a drawing."""
    width, height = png_size(path.read_bytes())
    from matplotlib.image import imread

    pixels = imread(str(path))
    assert pixels.shape[:2] == (height, width)
    assert float(np.ptp(pixels[..., :3])) > 0.5  # not a blank canvas
    return width, height


@pytest.mark.slow
def test_solve_plot_six_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal, png = tmp_path / "cal.json", tmp_path / "poses.png"
    code, _, err = run(capsys, "solve", "-p", *SIX, "--reference", "9.81", "-o", str(cal), "--plot", str(png), "-q")
    assert code == 0, err
    width, height = drawn_png_size(png)
    assert width > 300
    assert height > 300
    assert cal.exists()


@pytest.mark.slow
def test_solve_plot_magnetometer(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(7)
    turn = write_mag(tmp_path / "turn.csv", magnetometer(rng, sphere_directions(rng, 3000)))
    png = tmp_path / "mag.png"
    args = ["solve", "--sensor", "magnetometer", "--reference", str(FIELD), "-p", str(turn), "--plot", str(png)]
    code, _, err = run(capsys, *args, "-o", str(tmp_path / "cal.json"), "-q")
    assert code == 0, err
    width, height = drawn_png_size(png)
    assert width > height  # three planes side by side


@pytest.mark.slow
def test_solve_plot_is_written_on_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A unit outside its limits still has its calibration archived, and its figure."""
    png = tmp_path / "p.png"
    args = ["solve", "-p", *THREE, "--max-offset", "0.001", "-o", str(tmp_path / "cal.json"), "--plot", str(png)]
    code, _, _ = run(capsys, *args, "-q")
    assert code == 1
    drawn_png_size(png)


def test_solve_plot_not_written_when_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Exit 3 writes nothing: neither the calibration nor the figure (an old one stays as it was)."""
    png = tmp_path / "p.png"
    png.write_bytes(b"old")
    swapped = unnamed([THREE[1], THREE[0], THREE[2]], tmp_path / "unnamed")  # their order gives the faces
    code, _, err = run(capsys, "solve", "-p", *swapped, "-o", str(tmp_path / "cal.json"), "--plot", str(png))
    assert code == 3, err
    assert png.read_bytes() == b"old"
    assert not (tmp_path / "cal.json").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--plot", "-"], "--plot - would share stdout"),
        (["--plot", "SAME.png", "-o", "SAME.png"], "--plot and -o name the same file"),
        (["--plot", THREE[0], "-o", "cal.json"], "--plot writes a PNG image: give a file name ending in .png"),
        (["--plot", ".", "-o", "cal.json"], "--plot writes a PNG image"),
        (["--plot", "no/such/folder/p.png", "-o", "cal.json"], "the output folder does not exist"),
    ],
)
def test_solve_plot_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, extra: list[str], message: str
) -> None:
    monkeypatch.chdir(tmp_path)
    before = Path(THREE[0]).read_bytes()
    code, out, err = run(capsys, "solve", "-p", *THREE, *extra)
    assert (code, out) == (2, ""), err
    assert message in err
    assert Path(THREE[0]).read_bytes() == before
    assert not (tmp_path / "cal.json").exists()


def test_plot_without_matplotlib_is_one_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "matplotlib" else real(name, *a))
    cal = tmp_path / "cal.json"
    code, _, err = run(capsys, "solve", "-p", *THREE, "-o", str(cal), "--plot", str(tmp_path / "p.png"))
    assert code == 2
    assert "pip install 'tumblecal[plot]'" in err
    assert not cal.exists()  # refused before any work
    code, out, err = run(capsys, "report", str(LOT), "--plot", str(tmp_path / "lot.png"))
    assert (code, out) == (2, "")
    assert "tumblecal[plot]" in err


@pytest.mark.slow
def test_report_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "lot.png"
    code, out, err = run(capsys, "report", str(LOT), "--plot", str(png), "--outlier-alpha", "0.05")
    assert code == 1  # the sample lot's outlier
    assert out.startswith("sensor,parameter,")
    assert f"wrote {png}" in err
    width, height = drawn_png_size(png)
    assert width > height  # six histograms, four to a row


def test_batch_has_no_plot_option(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "batch", str(ROOT / "sample_data" / "lot.csv"), "--plot", "x.png")
    assert code == 2
    assert "No such option: --plot" in err


@pytest.mark.slow
def test_solve_without_plot_does_not_import_matplotlib(tmp_path: Path) -> None:
    body = (
        "import contextlib, io\n"
        "from tumblecal_cli.cli import main\n"
        "with contextlib.redirect_stderr(io.StringIO()):\n"
        f"    assert main(['solve', '--poses', *{THREE!r}, '-o', {str(tmp_path / 'c.json')!r}]) == 0\n"
        f"    assert main(['report', {str(LOT)!r}, '--json', '--outlier-alpha', '0.05']) == 1\n"
    )
    assert (
        imported(
            f"import contextlib, io\nwith contextlib.redirect_stdout(io.StringIO()):\n    exec({body!r})",
            ("matplotlib",),
        )
        == []
    )
