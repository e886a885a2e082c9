"""Long pose files summed as they are read (io.csv.posefile, core.running): a pose file of more
than ``posefile.SUMMED_ROWS`` readings is judged by running sums, its readings kept on disk.
Here that threshold is lowered and files are read in small blocks, so that real files of a few
hundred rows take the summed path across many blocks: every figure, check and note must be
what the in-memory path gives (figures to 1e-12), for floats and integer counts, a pose that
moved and is cut to its still run, a saturated pose, stdin, a compressed file and quoted
numbers. Peak memory is pinned by tests/test_hostile_memory.py.
"""

from __future__ import annotations

import gzip
import json
import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import IMUCAL, SAMPLE, feed_stdin, run, write
from tumblecal_cli.core import model
from tumblecal_cli.core.running import Summary
from tumblecal_cli.io.csv import capture, posefile

ROOT = Path(__file__).resolve().parent.parent
MOTION = ROOT / "tests" / "data" / "ncsu_microstrain_motion"
BLOCK = 700  # bytes: a block of some 20 rows


def _close(a: object, b: object, where: str = "", scale: float = 1.0) -> None:
    """Two JSON documents equal, their floats to 1e-12 (relative; or, below 1e-3 times the
    readings' ``scale``, absolute to 1e-13 of it: a difference of two near means, such as a
    drift, where the last digit of either mean shows)."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert sorted(a) == sorted(b), where
        for k in a:
            if k != "created":
                _close(a[k], b[k], f"{where}.{k}", scale)
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), where
        for x, y in zip(a, b, strict=True):
            _close(x, y, where, scale)
    elif isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-13 * scale if abs(a) < 1e-3 * scale else 0.0), (
            where,
            a,
            b,
        )
    else:
        assert a == b, (where, a, b)


def _both(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path, *args: str | Path
) -> tuple[tuple[int, str, object], tuple[int, str, object]]:
    """``tumblecal solve ARGS -o cal.json`` (or verify, when ARGS say so) read in memory and then
    summed: each run's exit status, stderr and what it wrote (None: nothing)."""
    out = []
    for summed in (False, True):
        with monkeypatch.context() as m:
            m.setattr(capture, "BLOCK_BYTES", BLOCK)
            if summed:
                m.setattr(posefile, "SUMMED_ROWS", 30)
            cal = tmp_path / f"cal{int(summed)}.json"
            r = run(capsys, *args, *(["-o", cal] if args[0] == "solve" else ["--json"]))
            text = r.out if args[0] == "verify" else (cal.read_text() if cal.exists() else None)
            out.append((r.code, r.err, None if text is None else json.loads(text)))
    return out[0], out[1]


def _same(
    capsys: pytest.CaptureFixture[str], mp: pytest.MonkeyPatch, tmp_path: Path, *args: str | Path, scale: float = 1.0
) -> str:
    whole, summed = _both(capsys, mp, tmp_path, *args)
    assert whole[0] == summed[0], summed[1]
    assert re.sub(r"cal[01]\.json", "", whole[1]) == re.sub(r"cal[01]\.json", "", summed[1])
    _close(whole[2], summed[2], scale=scale)
    return summed[1]


def test_a_long_pose_file_is_summed_to_the_figures_read_in_memory(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The sample unit (floats in g) and imucal's six faces (integer counts: the integer type's
    rails judged on the running lowest and highest), each pose summed over some 50 blocks."""
    xyz = [SAMPLE / f"{a}.csv" for a in "xyz"]
    _same(capsys, monkeypatch, tmp_path, "solve", "--poses", *xyz)
    six = [IMUCAL / f"{f}.csv" for f in ("xp", "xn", "yp", "yn", "zp", "zn")]
    _same(capsys, monkeypatch, tmp_path, "solve", "--poses", *six, "--reference", "2048", scale=2048)
    _same(capsys, monkeypatch, tmp_path, "verify", "-c", ROOT / "sample_data" / "lot" / _first_cal(), *xyz)


def _first_cal() -> str:
    return sorted(p.name for p in (ROOT / "sample_data" / "lot").glob("SN0001_*.json"))[0]


def test_a_long_pose_that_moved_is_cut_to_its_still_run_as_in_memory(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Six real files that start still and then log the handling: each judged moved by its
    running sums, and cut to the same still run (its readings mapped back from disk)."""
    files = [MOTION / f"{n}.csv" for n in ("xplus", "xminus", "yplus", "yminus", "zplus", "zminus")]
    err = _same(capsys, monkeypatch, tmp_path, "solve", "--poses", *files)
    assert err.count("the unit moved while it logged; solved from its still run") == 6


def test_a_long_saturated_pose_is_rejected_as_in_memory(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Readings at --full-scale: the same count of clipped rows, read again from the blocks
    that reach the level."""
    rng = np.random.default_rng(3)
    files = []
    for k, up in enumerate(np.eye(3)):
        v = up + 0.001 * rng.standard_normal((400, 3))
        if k == 0:
            v[100:117, 0] = 1.5  # 17 rows at the sensor's limit
        files.append(write(tmp_path / f"{'xyz'[k]}.csv", v, header="ax,ay,az"))
    err = _same(capsys, monkeypatch, tmp_path, "solve", "--poses", *files, "--full-scale", "1.5", "--no-trim")
    assert "17 samples clipped at 98% of --full-scale 1.5" in err


def test_a_long_pose_from_stdin_compressed_or_quoted_is_summed_as_in_memory(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """stdin (read once: its readings kept on disk as it is read), a gzip file, and a file whose
    numbers are quoted."""
    x, y, z = (SAMPLE / f"{a}.csv" for a in "xyz")
    packed = tmp_path / "x.csv.gz"
    packed.write_bytes(gzip.compress(x.read_bytes()))
    _same(capsys, monkeypatch, tmp_path, "solve", "--poses", packed, y, z)
    lines = x.read_text().splitlines()
    quoted = write(
        tmp_path / "q.csv",
        "\n".join([lines[0], *(",".join(f'"{c}"' for c in ln.split(",")) for ln in lines[1:])]) + "\n",
    )
    _same(capsys, monkeypatch, tmp_path, "solve", "--poses", quoted, y, z)
    data = x.read_bytes()
    whole: list[object] = []
    summed: list[object] = []
    for target, rows in ((whole, 10**9), (summed, 30)):
        with monkeypatch.context() as m:
            m.setattr(capture, "BLOCK_BYTES", BLOCK)
            m.setattr(posefile, "SUMMED_ROWS", rows)
            feed_stdin(m, data)
            r = run(capsys, "solve", "--poses", "+x=-", f"+y={y}", f"+z={z}", "-o", tmp_path / "s.json")
            assert r.code == 0, r.err
            target.append(json.loads((tmp_path / "s.json").read_text()))
    _close(whole[0], summed[0])


def test_running_sums_match_the_two_pass_statistics_of_the_readings() -> None:
    """Blocks of any size merged: mean, standard deviation, drift of the thirds and extremes as
    numpy computes them on the whole (a mean 1e4 above its noise: no cancellation)."""
    rng = np.random.default_rng(11)
    values = 1e4 + rng.standard_normal((10_007, 3))
    summary = Summary()
    for start, size in ((0, 1), (1, 4000), (4001, 17), (4018, 5989)):
        summary.add(values[start : start + size])
    summary.values = values
    st, exact = model.pose_stats(summary), model.pose_stats(values)
    assert np.allclose(st.mean, exact.mean, rtol=1e-14, atol=0)
    assert np.allclose(st.std, exact.std, rtol=1e-11, atol=0)
    third = len(values) // 3
    drift = values[-third:].mean(axis=0) - values[:third].mean(axis=0)
    assert np.allclose(summary.drift(), drift, rtol=0, atol=1e-10)
    assert (summary.low, summary.high) == (float(values.min()), float(values.max()))
    assert summary.at_level(1e4 - 3, 1e4 + 3) == int(((values <= 1e4 - 3) | (values >= 1e4 + 3)).any(axis=1).sum())


def test_a_long_pose_with_no_room_for_its_readings_is_one_error(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A $TMPDIR that cannot take the readings: exit 2 naming the pose file and the folder."""
    import tempfile

    from tests.conftest import assert_one_error

    missing = tmp_path / "gone"
    monkeypatch.setattr(tempfile, "tempdir", str(missing))
    monkeypatch.setattr(posefile, "SUMMED_ROWS", 30)
    x = SAMPLE / "x.csv"
    r = run(capsys, "verify", "-c", ROOT / "sample_data" / "lot" / _first_cal(), x)
    assert_one_error(
        r,
        f"{x}: its readings are kept in {missing} as it is read (a long pose file): No such file or directory",
        hint="set TMPDIR to a folder with room",
    )


def test_a_pose_file_past_the_room_in_tmpdir_ends_as_an_endless_stream(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The readings a long pose keeps on disk are bounded as segment's spool is (at most 4 GiB,
    never the disk's last margin): an endless stdin ends in exit 2, not a full $TMPDIR."""
    from tests.conftest import assert_one_error

    monkeypatch.setattr(posefile, "SUMMED_ROWS", 30)
    monkeypatch.setattr(posefile, "spool_room", lambda _folder: 10_000)
    x = SAMPLE / "x.csv"
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", x, SAMPLE / "y.csv", SAMPLE / "z.csv", "-o", out)
    assert_one_error(
        r,
        f"{x}: more than 0 MiB of readings to keep in {tempfile.gettempdir()} (at most 4 GiB, and the free space "
        "there less a margin): an endless stream?",
        hint="give a pose file of fewer rows",
    )
    assert not out.exists()
