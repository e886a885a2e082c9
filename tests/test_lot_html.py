"""report's lot figures (failing units and outliers marked, limits drawn or pointed at) and
report --html: one self-contained page, checked as text and in a real headless browser."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from tests.conftest import run
from tests.lotgen import FAILING, OUTLIERS, write_lot
from tumblecal_cli.io.figures import lothtml, plots
from tumblecal_cli.pipeline import report as reports

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

ROOT = Path(__file__).resolve().parent.parent
LIMITS = ROOT / "sample_data" / "limits.yaml"


@pytest.fixture(scope="module")
def lot_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("lot") / "cals"
    write_lot(folder)
    return folder


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    kept: list[Figure] = []
    monkeypatch.setattr(plots, "write_png", lambda fig, path: kept.append(fig))
    return kept


def named(ax: Axes) -> list[str]:
    return sorted(t.get_text() for t in ax.texts if not t.get_text().startswith(("limit", "←", "+")))


# --- the lot figure -------------------------------------------------------------------------------


def test_the_marked_units_are_the_failing_ones_and_the_outliers(lot_dir: Path, figures: list[Figure]) -> None:
    reported = reports.report([str(lot_dir)], limits=str(LIMITS))
    plots.lot_figure("unused.png", reports.histograms(reported))
    (fig,) = figures
    axes = {ax.get_title().split(" ")[0]: ax for ax in fig.axes}
    marked = {name: named(ax) for name, ax in axes.items() if named(ax)}
    assert marked == {"offset.x": ["SN0013"], "gain.y": ["SN0042"], "cross.xy": ["SN0021"]}
    assert set(OUTLIERS) | FAILING == {"SN0013", "SN0021", "SN0042"}
    # SN0013 fails and is an outlier: drawn as failing (red), counted as both in the title
    assert axes["offset.x"].get_title() == "offset.x (n=60, 1 outside, 1 outlier)"
    (points,) = axes["offset.x"].collections
    assert np.asarray(points.get_offsets())[0, 0] == pytest.approx(0.07)
    (points,) = axes["cross.xy"].collections
    assert np.asarray(points.get_offsets())[0, 0] == pytest.approx(0.003, rel=1e-3)


def test_limits_are_drawn_where_they_read_and_pointed_at_where_they_do_not(
    lot_dir: Path, figures: list[Figure]
) -> None:
    """Offsets' ±0.05 are lines; the cross terms' ±0.01 lie 20 spreads off: arrows with the value,
    and the x range stays the data's (the bars do not collapse to a line)."""
    reported = reports.report([str(lot_dir)], limits=str(LIMITS))
    plots.lot_figure("unused.png", reports.histograms(reported))
    axes = {ax.get_title().split(" ")[0]: ax for ax in figures[0].axes}
    _mean, lower, upper = axes["offset.x"].get_lines()
    assert (np.asarray(lower.get_xdata())[0], np.asarray(upper.get_xdata())[0]) == (-0.05, 0.05)
    assert lower.get_linestyle() == "--"
    cross = axes["cross.xz"]
    assert len(cross.get_lines()) == 1  # the mean only
    assert sorted(t.get_text() for t in cross.texts) == ["limit 0.01 →", "← limit −0.01"]
    left, right = cross.get_xlim()
    values = [e.values["cross.xz"] for e in reported.entries]
    assert left <= min(values) < max(values) <= right
    assert right - left < 3 * (max(values) - min(values))


def test_the_figure_of_the_lot_is_drawn_as_png(
    lot_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = tmp_path / "lot.png"
    code, _, err = run(capsys, "report", str(lot_dir), "--limits", str(LIMITS), "--plot", str(png))
    assert code == 1, err
    assert png.read_bytes().startswith(b"\x89PNG")


# --- the HTML page, as text -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def page(lot_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("html") / "site" / "lot.html"
    out.parent.mkdir()
    reported = reports.report([str(lot_dir)], limits=str(LIMITS), max_drift="offset=0.01")
    reports.write_html(reported, str(out), limits=str(LIMITS), drift_given=True)
    return out


def test_the_page_is_self_contained(page: Path) -> None:
    text = page.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert "<script" not in text
    assert not re.search(r"""(src|href)=["']?(https?:|//)""", text)  # nothing fetched
    assert "@import" not in text
    assert not re.search(r"url\((?!#)", text)  # only references inside the page (clip paths)
    ids = re.findall(r' id="([^"]+)"', text)
    assert sorted({i for i in ids if ids.count(i) > 1}) == []  # the inline SVGs' ids do not clash
    assert "@font-face" not in text
    assert lothtml.POLICY in text  # and the browser is told so
    assert text.count("<svg") == 12  # one per figure
    assert "<?xml" not in text


def test_the_page_says_verdict_yield_cpk_and_why(page: Path) -> None:
    text = page.read_text(encoding="utf-8")
    assert "Lot: Needs attention" in text
    assert "Yield: 58 of 60 units (96.7%) pass." in text
    assert "Bissell 1990" in text
    row = re.search(r"<tr class=\"fail\"><td class=\"l\">offset\.x</td>.*?</tr>", text)
    assert row is not None
    assert "SN0013 (t +8.0)" in row.group(0)
    assert re.search(r"<td>1\.3</td><td>1\.05 … 1\.55</td>", row.group(0))  # Cpk and its interval
    assert "offset.x 0.07 outside −0.05 … 0.05".replace("−", "-") in text
    assert "cross.xy 0.003: an outlier, t +15.8 against the other units (limit 4.94)" in text
    assert '<table id="stations">' in text
    assert '<td class="l">bay-1</td><td>30</td>' in text


def test_each_unit_links_to_its_calibration_relative_to_the_page(page: Path, lot_dir: Path) -> None:
    text = page.read_text(encoding="utf-8")
    links = re.findall(r'<a href="([^"]+)">(SN\d{4})</a>', text)
    assert len({serial for _, serial in links}) == 60
    for href, serial in links:
        assert not href.startswith("/")
        target = (page.parent / href).resolve()
        assert target.exists()
        assert json.loads(target.read_text())["unit"]["serial"] == serial


def test_html_from_the_command_line(lot_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "lot.html"
    code, csv_out, err = run(capsys, "report", str(lot_dir), "--limits", str(LIMITS), "--html", str(out))
    assert code == 1, err
    assert csv_out.startswith("sensor,parameter,")
    assert f"wrote {out}" in err
    assert [p.name for p in tmp_path.iterdir()] == ["lot.html"]  # atomic: no temporary file left


@pytest.mark.parametrize(
    ("target", "message"),
    [
        ("{tmp}", "is a folder: --html takes a file name"),
        ("{tmp}/", "names a folder"),
        ("/proc/lot.html", "cannot write into /proc"),
        ("{tmp}/missing/lot.html", "the output folder does not exist"),
        ("{tmp}/lot.txt", "--html writes a web page: give a file name ending in .html"),
    ],
)
def test_html_that_cannot_be_written_is_one_line_and_exit_2(
    target: str, message: str, lot_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = sorted(tmp_path.iterdir())
    code, out, err = run(capsys, "report", str(lot_dir), "--html", target.format(tmp=tmp_path))
    assert (code, out) == (2, "")  # before any work: no CSV either
    assert message in err
    assert len([line for line in err.splitlines() if line.startswith("error:")]) == 1
    assert "Traceback" not in err
    assert sorted(tmp_path.iterdir()) == before


def test_html_onto_a_calibration_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "cals"
    write_lot(folder, n=10)
    victim = folder / "SN0001_20261121.json"
    copy = tmp_path / "lot.html"
    shutil.copy(victim, copy)
    before = victim.read_bytes()
    code, _, err = run(capsys, "report", str(folder), str(copy), "--html", str(copy))
    assert code == 2
    assert "--html would overwrite the input" in err
    assert victim.read_bytes() == before


def test_outlier_alpha_out_of_range_writes_no_html(
    lot_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "lot.html"
    code, stdout, err = run(capsys, "report", str(lot_dir), "--html", str(out), "--outlier-alpha", "2")
    assert (code, stdout) == (2, "")
    assert "--outlier-alpha must be a probability between 0 and 1" in err
    assert not out.exists()


# --- the HTML page, in a real browser -------------------------------------------------------------

CHROMIUM = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"]
CHROMIUM += ["--disable-background-networking", "--disable-component-update", "--disable-sync"]

#: Put at the top of a copy of the page: records errors, then reports on every figure in the DOM.
PROBE = """<script>
window.__errors = [];
window.addEventListener("error", e => window.__errors.push(String(e.message || e.target.src || e.type)), true);
window.addEventListener("load", () => {
  const figures = [...document.querySelectorAll("#distributions svg")].map(svg => {
    const box = svg.getBoundingClientRect();
    return {width: box.width, height: box.height, drawn: svg.querySelectorAll("path, use").length};
  });
  const out = document.createElement("pre");
  out.id = "probe";
  out.textContent = JSON.stringify({errors: window.__errors, figures});
  document.body.appendChild(out);
});
</script>"""


def chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        pytest.skip("no chromium: `make test` installs it with apt-get where it can (Debian: apt-get install chromium)")
    return found


def browse(browser: str, tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    profile = tmp_path / "profile"
    return subprocess.run(
        [browser, *CHROMIUM, f"--user-data-dir={profile}", *args],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
        env=dict(os.environ, HOME=str(tmp_path)),
    )


@pytest.mark.slow
def test_the_page_in_a_headless_browser(page: Path, tmp_path: Path) -> None:
    from PIL import Image

    browser = chromium()
    # 1. the page as written: no console message of level error, no refused request
    shot = tmp_path / "shot.png"
    done = browse(
        browser,
        tmp_path,
        "--enable-logging=stderr",
        "--v=0",
        "--window-size=1280,2400",
        f"--screenshot={shot}",
        page.as_uri(),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    console = [line for line in done.stderr.splitlines() if "CONSOLE" in line or "Refused" in line]
    assert console == []
    # 2. a screenshot that is not blank: many pixels off white, in more than one colour
    image = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    ink = (image < 235).any(axis=2)
    assert ink.mean() > 0.03
    assert len(np.unique(image[ink].reshape(-1, 3) // 32, axis=0)) >= 5  # text, bars, limits, marks, verdict box
    # 3. every figure laid out and drawn, and no error, seen from inside the page (a probe on a copy)
    probed = tmp_path / "probed.html"
    text = page.read_text(encoding="utf-8").replace(lothtml.POLICY, lothtml.POLICY + "; script-src 'unsafe-inline'")
    probed.write_text(text.replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    done = browse(browser, tmp_path, "--dump-dom", "--virtual-time-budget=5000", probed.as_uri())
    match = re.search(r'<pre id="probe">(.*?)</pre>', done.stdout, re.S)
    assert match is not None, done.stderr[-2000:]
    probe = json.loads(match.group(1).replace("&quot;", '"'))
    assert probe["errors"] == []
    assert len(probe["figures"]) == 12
    assert all(f["width"] > 100 and f["height"] > 50 and f["drawn"] > 20 for f in probe["figures"])


def test_no_page_when_a_file_cannot_be_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "cals"
    write_lot(folder, n=10)
    (folder / "broken.json").write_text('{"format": "tumblecal-calibration",')
    out = tmp_path / "lot.html"
    code, _, err = run(capsys, "report", str(folder), "--html", str(out))
    assert code == 2
    assert "not valid JSON" in err
    assert not out.exists()


def test_a_serial_cannot_put_markup_in_the_page(tmp_path: Path) -> None:
    folder = tmp_path / "cals"
    (path, *_) = write_lot(folder, n=40)
    doc = json.loads(path.read_text())
    doc["unit"]["serial"] = '<script>alert("x")</script>'
    doc["offset"][0] = 0.5  # an outlier: named in the figure, the table and the list
    path.write_text(json.dumps(doc))
    out = tmp_path / "lot.html"
    reports.write_html(reports.report([str(folder)]), str(out))
    text = out.read_text(encoding="utf-8")
    assert "<script" not in text
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in text
