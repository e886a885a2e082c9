"""tumblecal noise: the overlapping Allan deviation against allantools' oadev, the figures
recovered from synthetic captures of known truth (white noise + random walk + first-order
Gauss-Markov bias, several lengths), the command's exit statuses, --json, --kalibr, the Python
API, and the real Xsens still start."""

from __future__ import annotations

import gzip
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from tests.conftest import ROOT, feed_stdin, run, write
from tumblecal_cli.core import allan

DATA = ROOT / "tests" / "data"
RATE = 100.0
# the truth: white noise density N (units/√Hz), a Gauss-Markov bias (std SB, time constant T s),
# a random walk K (units/s/√Hz)
N, SB, T, K = 0.01, 0.0005, 10.0, 1e-4


def truth_adev(tau: Any) -> Any:
    """The model's Allan deviation (IEEE 952 C: white, correlated (Gauss-Markov), rate random walk)."""
    tau = np.asarray(tau, dtype=float)
    gm = (2 * SB**2 * T / tau) * (1 - (T / (2 * tau)) * (3 - 4 * np.exp(-tau / T) + np.exp(-2 * tau / T)))
    return np.sqrt(N**2 / tau + gm + K**2 * tau / 3)


TRUTH = {
    "noise_density": N,
    "bias_instability": float(truth_adev(np.geomspace(1, 1e5, 4000)).min() / 0.664),
    "random_walk": K,
}


def gauss_markov(e: Any, phi: float) -> Any:
    """b_k = phi b_{k-1} + e_k, in blocks (phi^-k stays finite within one)."""
    out = np.empty_like(e)
    start = np.zeros(e.shape[1])
    for a in range(0, len(e), 20000):
        block = e[a : a + 20000]
        k = np.arange(len(block))[:, None]
        out[a : a + len(block)] = phi**k * (start * phi + np.cumsum(block * phi ** (-k), axis=0))
        start = out[a + len(block) - 1]
    return out


def simulate(n: int, seed: int) -> Any:
    rng = np.random.default_rng(seed)
    tau0 = 1 / RATE
    white = rng.normal(0, N * math.sqrt(RATE), (n, 3))
    walk = np.cumsum(rng.normal(0, K * math.sqrt(tau0), (n, 3)), axis=0)
    phi = math.exp(-tau0 / T)
    e = rng.normal(0, SB * math.sqrt(1 - phi * phi), (n, 3))
    e[0] = rng.normal(0, SB, 3)
    return white + walk + gauss_markov(e, phi)


def curve_of(y: Any, **kwargs: Any) -> allan.Curve:
    stream = allan.AllanStream(**kwargs)
    for first in range(0, len(y), 7919):  # uneven blocks, as a reader hands them over
        stream.add(y[first : first + 7919])
    return stream.result(RATE)


def capture(path: Path, y: Any, *, time: bool = True) -> Path:
    """``y`` written as a capture: t (seconds at RATE), x, y, z, or without ``time`` x, y, z alone."""
    if time:
        return write(path, np.column_stack([np.arange(len(y)) / RATE, y]), fmt="%.9g")
    return write(path, y, header="x,y,z", fmt="%.9g")


# -- the deviation ---------------------------------------------------------------------------


def test_streamed_deviation_equals_the_textbook_sum() -> None:
    y = simulate(20_000, 1) + np.array([33000.0, -2.0, 0.5])
    curve = curve_of(y)
    np.testing.assert_allclose(curve.adev, allan.oadev(y, [int(m) for m in curve.m]), rtol=1e-9)
    assert list(curve.m) == [2**k for k in range(14)]  # octaves while a term fits (2m < n + 1)


@pytest.mark.slow  # 1.2M samples: the textbook sums take a second
def test_every_term_kept_across_the_history_moves_of_a_long_capture() -> None:
    # past 2 x 2**19 samples S's history is moved back to the start of its buffer (twice here), and
    # blocks over allan.CHUNK rows are cut: every term of every cluster up to 2**18 is still summed
    y = simulate(1_200_000, 4) + np.array([0.01, -0.02, 1.01])
    stream = allan.AllanStream()
    for first in range(0, len(y), 100_003):
        stream.add(y[first : first + 100_003])
    curve = stream.result(RATE)
    exact = curve.m <= allan.EXACT_MAX
    np.testing.assert_allclose(curve.adev[exact], allan.oadev(y, [int(m) for m in curve.m[exact]]), rtol=1e-9)
    assert list(curve.terms[exact]) == [len(y) + 1 - 2 * int(m) for m in curve.m[exact]]


@pytest.mark.slow  # importing allantools (and scipy) takes most of a second
def test_deviation_equals_allantools_oadev() -> None:
    allantools = pytest.importorskip("allantools")
    y = simulate(20_000, 1) + np.array([33000.0, -2.0, 0.5])  # raw counts' offset: removed before the sum
    curve = curve_of(y)
    for j in range(3):
        taus, dev, _, _ = allantools.oadev(y[:, j], rate=RATE, data_type="freq", taus=curve.tau)
        assert np.allclose(taus, curve.tau)
        np.testing.assert_allclose(curve.adev[: len(dev), j], dev, rtol=1e-9, atol=0)


def test_strided_large_clusters_stay_close_to_every_term() -> None:
    y = simulate(200_000, 2)
    strided = curve_of(y, exact_max=2**10, window=64)  # clusters above 1024 samples on a grid of 64 starts
    full = allan.oadev(y, [int(m) for m in strided.m])
    assert np.all(strided.m[strided.m > 2**10] % 16 == 0)
    np.testing.assert_allclose(strided.adev[strided.m <= 2**10], full[strided.m <= 2**10], rtol=1e-9)
    np.testing.assert_allclose(strided.adev, full, rtol=0.05)


def test_memory_does_not_grow_with_the_capture() -> None:
    def held(n: int) -> tuple[int, int]:
        stream = allan.AllanStream(exact_max=2**12, window=64)
        stream.add(simulate(n, 3))
        bound = stream.buffer.nbytes + len(stream.strided) * 2 * 64 * 3 * 8  # 2 x window values per cluster size
        return int(stream.buffer.nbytes + sum(s.tail.nbytes for s in stream.strided)), bound

    for n in (50_000, 200_000):
        used, bound = held(n)
        assert used <= bound == held(50_000)[1]


def test_confidence_interval_brackets_the_point_and_narrows_with_more_terms() -> None:
    curve = curve_of(simulate(50_000, 4))
    low, high = curve.interval()
    assert np.all(low <= curve.adev)
    assert np.all(curve.adev <= high)
    width = (high - low) / curve.adev
    assert np.all(np.diff(width[:8, 0]) > 0)  # fewer terms at longer cluster times: wider
    assert allan.chi2_quantile(0.5, 1000) == pytest.approx(1000 * (1 - 2 / 9000) ** 3)


# -- the figures from known truth ------------------------------------------------------------


def check_figures(curve: allan.Curve, expect_determined: set[str]) -> None:
    for j, figs in enumerate(allan.figures(curve)):
        for name in allan.NAMES:
            f = getattr(figs, name)
            if name not in expect_determined:
                continue
            assert f.value is not None, f"{name} on {'xyz'[j]}: {f.why}"
            assert f.uncertainty is not None
            assert abs(f.value - TRUTH[name]) <= f.uncertainty, (name, "xyz"[j], f.value, f.uncertainty, TRUTH[name])


def test_a_minute_gives_the_noise_density_and_nothing_it_cannot_show() -> None:
    curve = curve_of(simulate(6000, 5))
    check_figures(curve, {"noise_density"})
    for figs in allan.figures(curve):
        assert (figs.random_walk.value, figs.random_walk.uncertainty) == (None, None)
        assert figs.bias_instability.value is None
        assert "falling" in figs.bias_instability.why or "white-noise line" in figs.bias_instability.why


@pytest.mark.slow
def test_four_hours_show_the_floor() -> None:
    check_figures(curve_of(simulate(int(4 * 3600 * RATE), 3)), {"noise_density", "bias_instability"})


@pytest.mark.slow
def test_twelve_hours_show_every_figure() -> None:
    check_figures(curve_of(simulate(int(12 * 3600 * RATE), 4)), set(allan.NAMES))


# -- the command -----------------------------------------------------------------------------


def cal_file(path: Path, sensor: str, units: str | None) -> Path:
    doc = {
        "format": "tumblecal-calibration",
        "version": 1,
        "sensor": sensor,
        "method": "gyro-bias" if sensor == "gyroscope" else "one-pose",
        "reference": 0.0 if sensor == "gyroscope" else 1.0,
        "units": units,
        "columns": ["x", "y", "z"],
        "offset": [0.0, 0.0, 0.0],
        "matrix": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        "gain": [1.0, 1.0, 1.0],
    }
    path.write_text(json.dumps(doc))
    return path


@pytest.fixture(scope="module")
def still(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return capture(tmp_path_factory.mktemp("noise") / "still.csv", simulate(20_000, 6))


def test_json_shape_and_not_determined_as_null(still: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "noise", still, "--json", "-q")
    assert (r.code, r.err) == (0, "")
    doc = json.loads(r.out)
    assert list(doc)[:7] == ["status", "exit_status", "file", "sensor", "rate", "samples", "units"]
    assert (doc["status"], doc["rate"], doc["samples"], doc["units"], doc["verdict"]) == (
        "pass",
        100.0,
        20000,
        None,
        None,
    )
    assert set(doc["adev"]) >= {"tau", "x", "y", "z"}
    assert len(doc["adev"]["x"]) == len(doc["adev"]["tau"])
    assert doc["adev"]["tau"][0] == pytest.approx(0.01)
    for axis in "xyz":
        figs = doc["axes"][axis]
        assert set(figs) == set(allan.NAMES)
        assert figs["noise_density"]["units"] == "raw/√Hz"
        assert abs(figs["noise_density"]["value"] - N) <= figs["noise_density"]["uncertainty"]
        assert (figs["random_walk"]["value"], figs["random_walk"]["uncertainty"]) == (None, None)


def test_denser_taus_from_stdin_with_the_time_in_ms(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    y = simulate(3000, 11)
    path = tmp_path / "ms.csv"
    np.savetxt(path, np.column_stack([np.arange(3000) * 10.0, y]), delimiter=",", header="t_ms,x,y,z", comments="")
    feed_stdin(monkeypatch, path.read_bytes())
    r = run(capsys, "noise", "-", "--taus", "4", "--json", "-q")
    assert (r.code, r.err) == (0, "")
    doc = json.loads(r.out)
    assert (doc["file"], doc["rate"], doc["samples"]) == ("<stdin>", 100.0, 3000)
    m = [round(t * RATE) for t in doc["adev"]["tau"]]
    assert m[:8] == [1, 2, 3, 4, 5, 6, 7, 8]  # 2^(k/4) rounded, each once
    np.testing.assert_allclose(np.array([doc["adev"][a] for a in "xyz"]).T, allan.oadev(y, m), rtol=1e-9)
    r = run(capsys, "noise", path, "--taus", "0")
    assert (r.code, r.err) == (2, "error: --taus must be 1 to 64 points per octave, got 0\n")


def test_no_rate_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = capture(tmp_path / "no_time.csv", simulate(500, 7), time=False)
    r = run(capsys, "noise", path)
    assert r.code == 2
    assert r.err == (
        f"error: {path}: the sample rate is unknown: the capture has no time column\nhint: give --rate HZ\n"
    )
    assert run(capsys, "noise", path, "--rate", "100", "-q").code == 0


def test_limits_exit_1_with_the_verdict(still: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    limits = tmp_path / "limits.yaml"
    limits.write_text("noise_density: [0.02, 0.005, 0.02]\nrandom_walk: 1\n")
    r = run(capsys, "noise", still, "--limits", limits, "--json")
    assert r.code == 1
    verdict = json.loads(r.out)["verdict"]
    assert verdict["pass"] is False
    assert [f["code"] for f in verdict["failures"]] == ["limit.noise_density.y"]
    assert verdict["not_judged"] == ["random_walk.x", "random_walk.y", "random_walk.z"]
    assert "verdict: FAIL (limits: noise_density, random_walk)" in r.err
    limits.write_text("noise_density: 0.02\n")
    assert run(capsys, "noise", still, "--limits", limits, "-q").code == 0


def test_solve_ignores_the_noise_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    limits = tmp_path / "limits.yaml"
    limits.write_text("offset: 0.1\nnoise_density: 0.02\n")
    sample = ROOT / "sample_data"
    r = run(capsys, "solve", "-p", sample / "x.csv", sample / "y.csv", sample / "z.csv", "--limits", limits, "-q")
    assert r.code == 0


def test_a_step_is_exit_3_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    y = simulate(20_000, 8)
    y[12_000:, 2] += 0.5  # 5 x the per-sample noise
    path = capture(tmp_path / "bumped.csv", y)
    kalibr, plot = tmp_path / "imu.yaml", tmp_path / "adev.png"
    cal = cal_file(tmp_path / "acc.json", "accelerometer", "g")
    r = run(capsys, "noise", path, "--cal", cal, "--kalibr", kalibr, "--plot", plot, "--json")
    assert r.code == 3
    assert json.loads(r.out)["status"] == "rejected"
    assert f"error: {path}: block means jump by" in r.err
    assert "on z near sample 12032," in r.err
    assert not kalibr.exists()
    assert not plot.exists()


def test_a_drift_far_above_the_random_walk_is_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    y = simulate(20_000, 9)
    y[:, 0] += np.linspace(0.0, 2.0, len(y))  # a warming unit: 2 (20 x the per-sample noise) over 200 s
    r = run(capsys, "noise", capture(tmp_path / "drift.csv", y))
    assert r.code == 3
    assert "drifts" in r.err
    assert " on x from start to end" in r.err


@pytest.mark.parametrize("log", ["hassan_mobile_30orient.csv", "xsens_acc.txt.gz"])
def test_a_real_log_tumbled_by_hand_is_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str], log: str) -> None:
    """Real logs of poses held between hand turns: each jump is one of many, so neither the
    step nor the drift rule saw them, and noise printed figures of the motion with exit 0."""
    path, options = DATA / "logs" / log, ["--rate", "100"]
    if log.endswith(".gz"):  # Xsens: t and three columns of counts, no header
        path = tmp_path / "xsens_acc.txt"
        path.write_bytes(gzip.decompress((DATA / "logs" / log).read_bytes()))
        options += ["--no-header", "--columns", "1,2,3"]
    r = run(capsys, "noise", path, *options, "--json")
    assert r.code == 3, r.err
    assert json.loads(r.out)["status"] == "rejected"
    assert "from one block to the next" in r.err
    assert "times the noise within a block (not a still capture)" in r.err


def low_passed(rng: np.random.Generator, n: int, rate: float, corner: float, poles: int) -> Any:
    """White noise through ``poles`` one-pole low-pass filters at ``corner`` Hz, settled (the
    filters' start, ten time constants a pole, left out)."""
    a = math.exp(-2 * math.pi * corner / rate)
    settle = poles * round(10 * rate / (2 * math.pi * corner))
    y = rng.normal(0.0, 0.01, (n + settle, 3))
    for _ in range(poles):
        out = np.empty_like(y)
        out[0] = y[0]
        for i in range(1, len(y)):
            out[i] = a * out[i - 1] + (1 - a) * y[i]
        y = out
    return y[settle:]


@pytest.mark.parametrize(
    ("rate", "corner", "poles"),
    [
        pytest.param(1000.0, 1.0, 1, id="1-Hz-at-1-kHz", marks=pytest.mark.slow),
        pytest.param(100.0, 0.2, 2, id="two-poles-0.2-Hz"),  # 3.0 of the noise within a block
        pytest.param(100.0, 0.05, 2, id="two-poles-0.05-Hz"),  # 4-5
    ],
)
def test_still_noise_filtered_far_below_its_rate_is_not_moving(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], rate: float, corner: float, poles: int
) -> None:
    """A sensor filtered far below its rate: its block means change smoothly, by up to sqrt(12)
    of the spread within a block, which a factor of 3 took for motion (exit 3 on a still unit)."""
    y = low_passed(np.random.default_rng(12), 30_000 if rate == 100.0 else 120_000, rate, corner, poles)
    path = capture(tmp_path / "filtered.csv", y, time=False)
    r = run(capsys, "noise", path, "--rate", f"{rate:g}", "-q")
    assert r.code == 0, r.err


@pytest.mark.slow
def test_kalibr_in_si_from_a_gyroscope_in_degrees(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(10)  # white noise 0.01 °/s/√Hz and a strong random walk 0.01 °/s²/√Hz, 2 h
    shape = (int(2 * 3600 * RATE), 3)
    y = rng.normal(0, 0.01 * math.sqrt(RATE), shape) + np.cumsum(rng.normal(0, 0.01 / math.sqrt(RATE), shape), 0)
    path = capture(tmp_path / "gyro.csv", y)
    cal = cal_file(tmp_path / "gyro.json", "gyroscope", "deg/s")
    kalibr = tmp_path / "imu.yaml"
    kalibr.write_text("rostopic: /imu0\naccelerometer_noise_density: 0.002\n")
    r = run(capsys, "noise", path, "--cal", cal, "--kalibr", kalibr, "--json", "-q")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["axes"]["x"]["noise_density"]["units"] == "°/√h"
    assert doc["axes"]["x"]["bias_instability"]["units"] == "°/h"
    model = yaml.safe_load(kalibr.read_text())
    assert (model["rostopic"], model["accelerometer_noise_density"]) == ("/imu0", 0.002)  # kept
    assert model["update_rate"] == 100.0
    worst = max(doc["axes"][a]["noise_density"]["value"] for a in "xyz")
    assert model["gyroscope_noise_density"] == pytest.approx(worst / 60 * math.pi / 180)
    assert model["gyroscope_noise_density"] == pytest.approx(0.01 * math.pi / 180, rel=0.05)
    assert model["gyroscope_random_walk"] == pytest.approx(0.01 * math.pi / 180, rel=0.5)
    devnull = run(capsys, "noise", path, "--cal", cal, "--kalibr", "/dev/null", "-q")  # was 'empty Kalibr imu.yaml'
    assert devnull.code == 0, devnull.err


def test_kalibr_needs_known_units_and_a_shown_random_walk(
    still: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kalibr = tmp_path / "imu.yaml"
    r = run(capsys, "noise", still, "--kalibr", kalibr)
    assert r.code == 2
    assert r.err == (
        "error: --kalibr needs --cal: Kalibr's figures are in SI, and raw readings have no known units\n"
        "hint: give the calibration of this sensor (its units: g, m/s^2, deg/s or rad/s)\n"
    )
    r = run(
        capsys, "noise", still, "--cal", cal_file(tmp_path / "c.json", "accelerometer", "counts"), "--kalibr", kalibr
    )
    assert (r.code, r.err.splitlines()[0]) == (
        2,
        "error: --units si needs a calibration in known accelerometer units, not 'counts'",
    )
    cal = cal_file(tmp_path / "acc.json", "accelerometer", "g")
    plot = tmp_path / "adev.png"
    r = run(capsys, "noise", still, "--cal", cal, "--kalibr", kalibr, "--plot", plot, "-q", "--json")
    assert r.code == 3
    assert json.loads(r.out)["status"] == "rejected"
    assert "random walk is not determined on every axis, and Kalibr needs it" in r.err
    assert not kalibr.exists()
    assert not plot.exists()


def test_accelerometer_in_g_reads_in_micro_g(still: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = cal_file(tmp_path / "acc.json", "accelerometer", "g")
    doc = json.loads(run(capsys, "noise", still, "--cal", cal, "--json", "-q").out)
    nd = doc["axes"]["y"]["noise_density"]
    assert (nd["units"], doc["units"]) == ("µg/√Hz", "g")
    assert nd["value"] == pytest.approx(N * 1e6, rel=0.05)
    native = json.loads(run(capsys, "noise", still, "--cal", cal, "--units", "native", "--json", "-q").out)
    assert native["axes"]["y"]["noise_density"]["value"] == pytest.approx(nd["value"] / 1e6)


def test_python_api(still: Path) -> None:
    import tumblecal_cli as tumblecal

    done = tumblecal.noise(still)
    assert (done.status, done.samples, done.rate) == (0, 20000, 100.0)
    assert done.axes[0].noise_density.value == pytest.approx(N, rel=0.05)
    assert done.to_dict()["axes"]["z"]["random_walk"]["value"] is None


@pytest.mark.slow
def test_plot_draws_a_png(still: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plot = tmp_path / "adev.png"
    assert run(capsys, "noise", still, "--plot", plot, "-q").code == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_real_xsens_still_start(capsys: pytest.CaptureFixture[str]) -> None:
    """The first 50 s of IMU-TK's Xsens session (raw counts, 100 Hz): white noise only shows."""
    acc = json.loads(run(capsys, "noise", DATA / "xsens_acc_still.txt", "--no-header", "--json", "-q").out)
    gyro = json.loads(
        run(capsys, "noise", DATA / "xsens_gyro_still.txt", "--no-header", "--sensor", "gyroscope", "--json", "-q").out
    )
    for doc, level in ((acc, 0.34), (gyro, 2.7)):
        assert (doc["status"], doc["rate"], doc["samples"]) == ("pass", 100.0, 5000)
        for axis in "xyz":
            figs = doc["axes"][axis]
            assert figs["noise_density"]["value"] == pytest.approx(level, rel=0.1)
            assert (figs["random_walk"]["value"], figs["bias_instability"]["value"]) == (None, None)


@pytest.mark.parametrize("flag", ["--plot", "--kalibr"])
def test_noise_never_writes_onto_its_input(flag: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capture = tmp_path / "still.png" if flag == "--plot" else tmp_path / "still.csv"
    text = "t,ax,ay,az\n" + "".join(f"{i / 100:.2f},0.01,0.02,1.0{i % 7}\n" for i in range(3000))
    capture.write_text(text)
    code, _, err = run(capsys, "noise", capture, flag, capture)
    assert code == 2, err
    assert "would overwrite the input" in err
    assert capture.read_text() == text


def test_a_plain_capture_read_where_its_cells_lie_gives_what_the_general_reader_gives(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A regular file of plain lines is parsed in place (pipeline.noise._spliced): the same
    output, every digit and every word, as the general reader's, on a plain capture and on the
    shapes that send it back to the general reader or past it (a comment half-way, CR LF line
    ends, no line end after the last line, a row without readings whose time is empty)."""
    from tumblecal_cli.pipeline import noise as noise_pipeline

    y = simulate(300_000, 11)
    plain = capture(tmp_path / "plain.csv", y)
    text = plain.read_text()
    lines = text.splitlines(keepends=True)
    shapes = {
        "plain": text,
        "noted": "".join([*lines[:200_000], "# the unit was bumped here\n", *lines[200_000:]]),
        "crlf": text.replace("\n", "\r\n"),
        "unended": text[:-1],
        "untimed-row": "".join([*lines[:150_000], ",,,\n", *lines[150_001:]]),
    }
    files = {name: tmp_path / f"{name}.csv" for name in shapes}
    for name, body in shapes.items():
        files[name].write_bytes(body.encode())

    def said(path: Path) -> tuple[int, str, str]:
        r = run(capsys, "noise", path, "--json")
        return r.code, r.out, r.err

    taken: list[str] = []
    spliced = noise_pipeline._spliced

    def spy(path: str, *rest: Any) -> Any:
        found = spliced(path, *rest)
        if found is not None:
            taken.append(os.path.basename(path))
        return found

    monkeypatch.setattr(noise_pipeline, "_spliced", spy)
    fast = {name: said(path) for name, path in files.items()}
    monkeypatch.setattr(noise_pipeline, "_spliced", lambda *a: None)
    general = {name: said(path) for name, path in files.items()}
    assert taken == ["plain.csv", "noted.csv", "untimed-row.csv"]  # (the noted one and the last fall back)
    assert fast == general
    assert fast["plain"][0] == 0
    assert json.loads(fast["plain"][1])["samples"] == 300_000
    assert fast["untimed-row"][0] == 2  # an empty time cell, on a row without readings too
