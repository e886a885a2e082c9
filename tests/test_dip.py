"""A magnetometer from a log with both sensors (pipeline.solve.maglog): the still blocks its
accelerometer finds, the samples between them where they widen the coverage, and the dip check:
each block's angle between gravity and the field against the World Magnetic Model's, in the file
and the summary, judged by the ``dip_angle`` limit (a field bent by steel fails), with an
uncertainty checked by Monte Carlo."""

from __future__ import annotations

import itertools
import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import assert_untouched, assert_usage_error, precious, run, write
from tumblecal_cli.core import alignment, earth
from tumblecal_cli.core.arrays import FloatArray

PLACE, DAY = "52.2053,0.1218,16", "2026-11-27"
FIELD = earth.magnetic_field(52.2053, 0.1218, 16.0, earth.decimal_year(2026, 11, 27))
#: the field in the local north-east-down frame, µT, and gravity's reading (up), g
NED_FIELD = np.array([FIELD.north, FIELD.east, FIELD.down]) / 1000.0
UP = np.array([0.0, 0.0, -1.0])  # an accelerometer at rest reads up; in NED, up is -down
HARD = np.array([12.0, -25.0, 30.0])
SOFT = np.array([[1.05, 0.03, -0.02], [0.03, 0.97, 0.04], [-0.02, 0.04, 1.01]])
RATE = 100.0


def rotation(rng: np.random.Generator) -> FloatArray:
    """A random rotation matrix (body from NED), uniform over orientations."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def both_sensors_log(
    rng: np.random.Generator,
    blocks: int = 16,
    *,
    disturbance: FloatArray | None = None,
    still_s: float = 2.0,
    turn_s: float = 1.0,
    mag_noise: float = 0.15,
    detour: bool = False,
) -> FloatArray:
    """t, ax, ay, az (g), mx, my, mz (raw µT through SOFT and HARD) of a unit put down in
    ``blocks`` random orientations, turned smoothly between them; ``disturbance`` (µT, NED) adds
    a field that is not the Earth's (a steel bench)."""
    field = NED_FIELD + (np.zeros(3) if disturbance is None else disturbance)
    turns = [rotation(rng) for _ in range(blocks)]
    acc, mag = [], []
    for k, r in enumerate(turns):
        n = int(still_s * RATE)
        acc.append(np.tile(r.T @ UP, (n, 1)) + rng.normal(0, 0.002, (n, 3)))
        mag.append(np.tile(r.T @ field, (n, 1)))
        if k + 1 < len(turns):  # a turn: the field and gravity swing (and the hand shakes)
            via = [r, rotation(rng), turns[k + 1]] if detour else [r, turns[k + 1]]
            for start, end in itertools.pairwise(via):
                m = int(turn_s * RATE / (len(via) - 1))
                s = np.linspace(0, 1, m)[:, None]
                a = (1 - s) * (start.T @ UP) + s * (end.T @ UP)
                b = (1 - s) * (start.T @ field) + s * (end.T @ field)
                acc.append(a / np.linalg.norm(a, axis=1, keepdims=True) + rng.normal(0, 0.2, (m, 3)))
                mag.append(b / np.linalg.norm(b, axis=1, keepdims=True) * np.linalg.norm(field))
    a_all, m_all = np.concatenate(acc), np.concatenate(mag)
    raw_mag = m_all @ SOFT.T + HARD + rng.normal(0, mag_noise, m_all.shape)
    t = np.arange(len(a_all)) / RATE
    return np.column_stack([t, a_all, raw_mag])


def write_log(path: Path, data: FloatArray) -> Path:
    return write(path, data, header="t,ax,ay,az,mx,my,mz", fmt="%.5f")


def accel_cal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """An ideal accelerometer calibration (offset 0, M = I), as solve writes it."""
    from tests.conftest import POSES_3

    out = tmp_path / "acc.json"
    assert run(capsys, "solve", "-p", *POSES_3, "-o", out).code == 0
    doc = json.loads(out.read_text())
    doc |= {"offset": [0.0, 0.0, 0.0], "matrix": [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]], "gain": [1.0, 1.0, 1.0]}
    out.write_text(json.dumps(doc))
    return out


def test_dip_of_ideal_readings_is_90_minus_the_inclination() -> None:
    rng = np.random.default_rng(3)
    rs = [rotation(rng) for _ in range(10)]
    d = earth.dip(np.array([r.T @ UP for r in rs]), np.array([r.T @ NED_FIELD for r in rs]))
    assert d.angles == pytest.approx(np.full(10, 90.0 - FIELD.inclination), abs=1e-9)
    assert (d.mean, d.spread) == pytest.approx((90.0 - FIELD.inclination, 0.0), abs=1e-9)


def test_a_magnetometer_from_a_log_with_both_sensors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    log = write_log(tmp_path / "both.csv", both_sensors_log(np.random.default_rng(11)))
    out = tmp_path / "mag.json"
    r = run(capsys, "solve", "--sensor", "magnetometer", "--log", log, "-o", out, "--location", PLACE, "--date", DAY)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "ellipsoid"
    assert np.array(doc["offset"]) == pytest.approx(HARD, abs=0.3)
    # corrected = M (raw - b) reads the Earth's field in every orientation
    truth = np.linalg.inv(SOFT)
    m = np.array(doc["matrix"])
    assert np.abs(m.T @ m - truth.T @ truth).max() < 0.01  # M up to a rotation (the ellipsoid's is symmetric)
    assert "dip" not in doc  # no accelerometer calibration: no dip angles
    assert "still blocks the accelerometer found" in r.err


def test_the_samples_between_still_blocks_are_taken_when_they_widen_coverage(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    log = write_log(tmp_path / "both.csv", both_sensors_log(np.random.default_rng(2), blocks=6, detour=True))
    r = run(capsys, "solve", "--sensor", "magnetometer", "--log", log, "-o", tmp_path / "m.json", "--reference", "49")
    assert r.code == 0, r.err
    assert re.search(r"and the \d+ samples between them, which widen its coverage from \d+% to \d+%", r.err), r.err


def test_the_dip_check_in_the_file_the_summary_and_the_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    log = write_log(tmp_path / "both.csv", both_sensors_log(np.random.default_rng(11)))
    out = tmp_path / "mag.json"
    args = ("solve", "--sensor", "magnetometer", "--log", log, "-o", out, "--location", PLACE, "--date", DAY)
    r = run(capsys, *args, "--accel-cal", accel_cal(tmp_path, capsys), "--json")
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    dip = doc["dip"]
    assert dip["blocks"] == 16
    assert dip["model_deg"] == pytest.approx(90 - FIELD.inclination, abs=1e-4)
    assert abs(dip["difference_deg"]) < 4 * dip["uncertainty_deg"] + 0.02
    assert dip["spread_deg"] < 0.5
    assert json.loads(r.out)["dip"] == dip
    said = "inclination: the field's angle below the horizontal, + down"
    assert f"dip {90 - dip['mean_deg']:.2f}° ± {dip['uncertainty_deg']}° ({said}) over" in r.err  # one convention
    assert "dip" in run(capsys, "show", out).out
    assert "below the horizontal" in run(capsys, "show", out).out


def test_a_field_bent_by_steel_fails_the_dip_angle_limit(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # a bench's steel adds 8 µT pointing north-up: the field the unit sees is not the model's
    log = write_log(
        tmp_path / "steel.csv",
        both_sensors_log(np.random.default_rng(11), disturbance=np.array([8.0, 0, -8.0]), detour=True),
    )
    limits = write(tmp_path / "limits.yaml", "dip_angle: 1.0\n")
    out = tmp_path / "mag.json"
    args = ("solve", "--sensor", "magnetometer", "--log", log, "-o", out, "--location", PLACE, "--date", DAY)
    r = run(capsys, *args, "--accel-cal", accel_cal(tmp_path, capsys), "--limits", limits)
    assert r.code == 1, r.err
    doc = json.loads(out.read_text())
    (failure,) = doc["verdict"]["failures"]
    assert failure["code"] == "limit.dip_angle"
    assert doc["verdict"]["limits"]["dip_angle"] == 1.0
    assert abs(failure["value"]) > 1.0
    clean = write_log(tmp_path / "clean.csv", both_sensors_log(np.random.default_rng(11), detour=True))
    r = run(capsys, *args[:4], clean, *args[5:], "--accel-cal", tmp_path / "acc.json", "--limits", limits)
    assert r.code == 0, r.err


@pytest.mark.slow
def test_the_dip_angles_uncertainty_holds_its_scatter_monte_carlo(tmp_path: Path) -> None:
    """The mean dip angle's 1σ (the blocks' spread / √n) against the truth over 40 logs: z-scores
    within ±3, their spread near 1."""
    import tumblecal_cli as tumblecal
    from tumblecal_cli.io.calfiles import calfile

    acc = calfile.Calibration(
        "accelerometer", "three-pose", 1.0, ["ax", "ay", "az"], np.zeros(3), np.eye(3), np.ones(3)
    )
    acc.save(tmp_path / "acc.json")
    truth = 90.0 - FIELD.inclination
    z = []
    for seed in range(40):
        data = both_sensors_log(np.random.default_rng(100 + seed), mag_noise=0.5, detour=True)
        log = write_log(tmp_path / "log.csv", data)
        solved = tumblecal.solve_log(
            str(log), sensor="magnetometer", location=PLACE, date=DAY, accel_cal=str(tmp_path / "acc.json")
        )
        assert solved.calibration is not None
        dip = solved.calibration.fields["dip"]
        assert isinstance(dip, dict)
        z.append((dip["mean_deg"] - truth) / dip["uncertainty_deg"])
    zs = np.array(z)
    assert np.abs(zs).max() < 3.0 + 0.5, zs  # 40 draws of a t with 15 degrees of freedom
    assert 0.6 < float(np.std(zs)) < 1.5, zs


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--pose-column", "part", "--accel-cal", "ACC"], ["--accel-cal", "dip check"]),
    ],
)
def test_bad_dip_checks_are_exit_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str], words: list[str]
) -> None:
    log = write_log(tmp_path / "both.csv", both_sensors_log(np.random.default_rng(1), blocks=4))
    acc = accel_cal(tmp_path, capsys)
    out = precious(tmp_path / "mag.json")
    given = [str(acc) if a == "ACC" else a for a in args]
    r = run(capsys, "solve", "--sensor", "magnetometer", "--log", log, *given, "-o", out)
    assert_usage_error(r, *words)
    assert_untouched(out)


def test_a_log_of_one_sensor_is_exit_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    data = both_sensors_log(np.random.default_rng(1), blocks=4)
    log = write(tmp_path / "acc.csv", data[:, :4], header="t,x,y,z", fmt="%.5f")
    r = run(capsys, "solve", "--sensor", "magnetometer", "--log", log, "-o", tmp_path / "m.json")
    assert_usage_error(r, "both sensors")


def test_check_judges_the_dip_angles_a_file_records_again(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    log = write_log(tmp_path / "both.csv", both_sensors_log(np.random.default_rng(11), detour=True))
    out = tmp_path / "mag.json"
    args = ("solve", "--sensor", "magnetometer", "--log", log, "-o", out, "--location", PLACE, "--date", DAY)
    assert run(capsys, *args, "--accel-cal", accel_cal(tmp_path, capsys)).code == 0
    assert run(capsys, "check", out, "--limits", write(tmp_path / "loose.yaml", "dip_angle: 1\n")).code == 0
    r = run(capsys, "check", out, "--limits", write(tmp_path / "tight.yaml", "dip_angle: 0.001\n"), "--json")
    assert r.code == 1, r.err
    assert [f["code"] for f in json.loads(r.out)["verdict"]["failures"]] == ["limit.dip_angle"]
    plain = tmp_path / "plain.json"
    assert run(capsys, *args[:6], plain, *args[7:]).code == 0
    r = run(capsys, "check", plain, "--limits", tmp_path / "loose.yaml")
    assert_usage_error(r, "has no dip angles to judge the dip_angle limit by")


def test_max_noise_judges_the_accelerometers_blocks_of_a_magnetometer_log(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """--max-noise was ignored there (the blocks were judged at 0.02 whatever was given): a real
    hand-held log, still to 0.05 g, could not be used, and a strict bound kept noisy blocks."""
    log = write_log(tmp_path / "both.csv", both_sensors_log(np.random.default_rng(11)))  # blocks still to 0.002 g
    out = tmp_path / "mag.json"
    strict = run(capsys, "solve", "--sensor", "magnetometer", "--log", log, "-o", out, "--max-noise", "0.001")
    assert strict.code == 3, strict.err
    assert "too noisy" in strict.err
    assert not out.exists()
    assert run(capsys, "solve", "--sensor", "magnetometer", "--log", log, "-o", out, "--max-noise", "0.01").code == 0


def test_a_magnetometer_log_of_separate_streams_says_so(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A PX4 log keeps sensor_mag apart from sensor_accel: it said 'sensor_mag:0 carries
    magnetometer, not the accelerometer; give --sensor magnetometer', which had been given."""
    import gzip

    ulog = tmp_path / "small.ulg"
    data = Path(__file__).resolve().parent / "data" / "px4" / "pyulog_sample_log_small.ulg.gz"
    ulog.write_bytes(gzip.decompress(data.read_bytes()))
    out = tmp_path / "mag.json"
    r = run(capsys, "solve", "--sensor", "magnetometer", "--log", ulog, "--stream", "sensor_mag:0", "-o", out)
    assert r.code == 2
    assert r.err.startswith(f"error: {ulog}: a magnetometer's --log reads both sensors on each row")
    assert "--poses LOG --stream" in r.err
    assert not out.exists()


def test_the_dip_angles_are_taken_through_the_alignment(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A magnetometer turned 3° from its accelerometer: each block's dip is off by up to 3°, and
    with --align-to the dips are taken through the aligned matrix, so their spread shrinks."""
    data = both_sensors_log(np.random.default_rng(11), mag_noise=0.05)
    turned = alignment.exp_map(np.radians(3.0) * np.array([1.0, 2.0, -1.0]) / np.sqrt(6.0))  # v_acc = turned v_mag
    field = (data[:, 4:] - HARD) @ np.linalg.inv(SOFT).T  # the field in the accelerometer's axes
    data[:, 4:] = (field @ turned) @ SOFT.T + HARD  # ... read in the magnetometer's
    log = write_log(tmp_path / "both.csv", data)
    acc = accel_cal(tmp_path, capsys)
    args = ("solve", "--sensor", "magnetometer", "--log", log, "--location", PLACE, "--date", DAY, "--accel-cal", acc)
    plain, aligned = tmp_path / "mag.json", tmp_path / "mag-aligned.json"
    assert run(capsys, *args, "-o", plain).code == 0
    r = run(capsys, *args, "--align-to", acc, "-o", aligned)
    assert r.code == 0, r.err
    assert "note: aligned to" in r.err
    before, after = (json.loads(p.read_text())["dip"] for p in (plain, aligned))
    assert before["spread_deg"] > 1.0
    assert after["spread_deg"] < before["spread_deg"] / 5
    assert abs(after["difference_deg"]) < 4 * after["uncertainty_deg"] + 0.02


def test_the_dip_parts_model_uncertainty_is_its_releases_own() -> None:
    """The dip part recorded WMM2025's 0.20° whichever release gave the field."""
    from tumblecal_cli.core import earth
    from tumblecal_cli.pipeline.solve.maglog import _inclination_error

    assert _inclination_error({"model": "WMM2020"}) == 0.21
    assert _inclination_error({"model": "WMM2025"}) == 0.20
    assert _inclination_error({"model": "WMM2010"}) is None
    assert earth.release_named("nonsense") is None
