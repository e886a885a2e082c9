"""`make bench`: tumblecal's speed as ratios against baselines measured in the same run.

Not a test (pytest does not collect it): timings depend on the machine. Each figure is the wall
clock of a fresh process and its peak memory (max RSS): for apply and its baseline the median of
five runs each, taking turns; elsewhere the best of a few runs.

    apply, 1M/4M/20M rows  vs  the polars script a user would write instead (POLARS_APPLY below:
                           scan_csv -> M (v - b) -> sink_csv; target <= 1x at 4M and 20M rows),
                           each run writing over the last one's output, and at 20M also each
                           run into a new file (the output removed before each run, both)
    apply, 2 sensors       vs  the same script with both calibrations (4M rows of t, acc, gyro)
    apply, pandas          vs  python -c "import pandas; pandas.read_csv(f)"  (4M rows: reading only)
    apply peak memory      20M rows / 1M rows (streaming: <= 1.3x), and 100,000 columns / 1M rows
    solve, 3 poses      vs  python -c "import pandas, numpy"               (start-up)
    segment, 600k rows  vs  python -c "import pandas; pandas.read_csv(f)"  (target <= 1.5x)
    segment, solve --log, 20M rows (a 5.6 h tumble session)  vs  the same read_csv; peak memory
    segment, solve --log, 5M and 20M rows of 20 s still and 3 s turning, on a few faces (1 kHz)
                           and in thousands of random orientations (100 Hz)  vs  POLARS_BLOCKS, the
                           polars script of the still blocks (rolling spread, threshold, runs,
                           block means; target <= 1.5x its wall time, peak memory <= its own),
                           five runs each taking turns, the median; segment -d vs segment (<= 1.5x)
    batch, 200 units    vs  a shell loop calling `tumblecal solve` per unit (target: 20x the units/s)
    noise, 4M and 10M samples  vs  pandas.read_csv + allantools.oadev per axis (octave taus), the same file
                           (three runs each taking turns, the median; target <= 0.3x)
    noise peak memory   10M samples / 2.5M samples  (streaming: ~1, not ~4)
    ULog stream, 100 MB vs pyulog.ULog(f, message_name_filter_list=["sensor_accel"]), the same log
                           (sensor_accel and sensor_gyro, two instances each, 1 kHz); peak memory
    DataFlash stream, 100 MB  vs pymavlink's DFReader_binary(f) and recv_match(type="IMU"), the
                           same log (IMU, ACC and GYR, two instances each, 1 kHz); peak memory

    ROS bag stream, 100 MB  vs  rosbags' AnyReader and deserialize of that topic, the same bag (a ROS 1
                           bag, and a ROS 2 bag in MCAP storage: two Imu topics at 1 kHz); peak memory

`python tests/bench.py against REV` (`make bench AGAINST=REV`) times every command of this tree
against the same command of git revision REV, in turns (nine runs each, the medians): whether a
change made anything slower.
`python tests/bench.py pace` runs the lines against POLARS_BLOCKS and the noise lines, `python tests/bench.py noise`
the noise lines alone, `python tests/bench.py ulog` the ULog one,
`python tests/bench.py dataflash` the DataFlash one, `python tests/bench.py ros` the ROS ones.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TUMBLECAL = [sys.executable, "-m", "tumblecal_cli"]
#: What a user would write instead of `tumblecal apply` (polars, installed by `make bench` only):
#: python -c POLARS_APPLY capture.csv out.csv cal.json [cal2.json ...]
POLARS_APPLY = """
import json, sys
import polars as pl
exprs = []
for path in sys.argv[3:]:
    cal = json.load(open(path)); M = cal["matrix"]; b = cal["offset"]; c = cal["columns"]
    v = [pl.col(n) - b[i] for i, n in enumerate(c)]
    exprs += [(M[r][0] * v[0] + M[r][1] * v[1] + M[r][2] * v[2]).alias(c[r]) for r in range(3)]
pl.scan_csv(sys.argv[1]).with_columns(exprs).sink_csv(sys.argv[2])
"""

#: What a user would write instead of `segment` or `solve --log` to find a log's still blocks
#: (polars, installed by `make bench` only), verbatim: python -c POLARS_BLOCKS log.csv
POLARS_BLOCKS = """
import sys, polars as pl
lf = pl.scan_csv(sys.argv[1]); cols = ["ax", "ay", "az"]
lf = lf.with_columns([pl.col(c).rolling_std(100, center=True).alias(c + "_s") for c in cols])
lf = lf.with_columns((pl.max_horizontal([pl.col(c + "_s") for c in cols]) < 0.01).alias("still"))
lf = lf.with_columns((pl.col("still") != pl.col("still").shift(1)).cum_sum().alias("run"))
res = (lf.filter(pl.col("still")).group_by("run").agg([pl.col(c).mean() for c in cols] + [pl.len().alias("n")])
       .filter(pl.col("n") >= 500).collect())
"""


def run(argv: list[str], repeat: int = 3, fresh: Path | None = None) -> tuple[float, float]:
    """Best wall time (s) and the peak RSS (MiB) of that run, each a fresh process, ``fresh``
    (a file or folder) removed before each. (Runs of tumblecal and its baseline come in the
    same call to `main`, one after the other.)"""
    import shutil

    best = (float("inf"), 0.0)
    for _ in range(repeat):
        if fresh is not None and fresh.is_dir():
            shutil.rmtree(fresh)
        elif fresh is not None:
            fresh.unlink(missing_ok=True)
        start = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        if status != 0:
            raise SystemExit(f"bench: {' '.join(argv)} failed: {proc.stderr.read().decode() if proc.stderr else ''}")
        if wall < best[0]:
            best = (wall, usage.ru_maxrss / 1024)
    return best


def paired(
    ours: list[str], base: list[str], repeat: int = 5, fresh: tuple[Path, Path] | None = None
) -> tuple[tuple[float, float], tuple[float, float]]:
    """``run`` for tumblecal and its baseline taking turns (ours, base, ours, base ...), so that
    a busy spell on a shared machine falls on both: the median wall time of each, with the
    highest peak RSS. ``fresh``: each one's output, removed before each of its runs."""
    import statistics

    a, b = [], []
    for _ in range(repeat):
        a.append(run(ours, repeat=1, fresh=fresh[0] if fresh else None))
        b.append(run(base, repeat=1, fresh=fresh[1] if fresh else None))
    return (
        (statistics.median(t for t, _ in a), max(m for _, m in a)),
        (statistics.median(t for t, _ in b), max(m for _, m in b)),
    )


def write_log(path: Path, rows: int) -> None:
    """A t,ax,ay,az capture at 1 kHz in g, 6 decimals, like a logger writes (the columns of
    sample_data, which the calibration records)."""
    rng = np.random.default_rng(1)
    with path.open("w") as f:
        f.write("t,ax,ay,az\n")
        for start in range(0, rows, 500_000):
            n = min(500_000, rows - start)
            t = np.arange(start, start + n) / 1000.0
            xyz = rng.normal([0.01, -0.02, 1.01], 0.01, size=(n, 3))
            np.savetxt(f, np.column_stack([t, xyz]), fmt=["%.3f", "%.6f", "%.6f", "%.6f"], delimiter=",")


def write_warm_log(path: Path, rows: int) -> None:
    """A t,temp,ax,ay,az capture at 1 kHz warming from 20 to 50 °C (the thermal bench)."""
    rng = np.random.default_rng(4)
    with path.open("w") as f:
        f.write("t,temp,ax,ay,az\n")
        for start in range(0, rows, 500_000):
            n = min(500_000, rows - start)
            k = np.arange(start, start + n)
            xyz = rng.normal([0.01, -0.02, 1.01], 0.01, size=(n, 3))
            columns = np.column_stack([k / 1000.0, 20.0 + 30.0 * k / rows, xyz])
            np.savetxt(f, columns, fmt=["%.3f", "%.2f", "%.6f", "%.6f", "%.6f"], delimiter=",")


def thermal_bench(folder: Path, cal: Path, rows: int = 1_000_000) -> tuple[str, float, float, str]:
    """apply with a thermal block (order 3) against apply without one, on one warming capture."""
    import json

    log = folder / "warm.csv"
    write_warm_log(log, rows)
    doc = json.loads(cal.read_text())
    doc["thermal"] = {
        "column": "temp",
        "reference_temperature": 25.0,
        "range": [0.0, 60.0],
        "order": 3,
        "offset": [[2e-4, 3e-6, 1e-8]] * 3,
        "gain": [[1e-4, 1e-7, 1e-9]] * 3,
        "gain_drift": ["separate"] * 3,
    }
    warm = folder / "warm-cal.json"
    warm.write_text(json.dumps(doc))
    out = str(folder / "out.csv")
    base, _ = run([*TUMBLECAL, "apply", "-q", "--cal", str(cal), str(log), "-o", out])
    ours, _ = run([*TUMBLECAL, "apply", "-q", "--cal", str(warm), str(log), "-o", out])
    size = log.stat().st_size / 1e6
    return (f"apply thermal 1M ({size:.0f} MB)", ours, base, "vs the same apply without a thermal block")


def write_imu(path: Path, rows: int) -> None:
    """A t,ax,ay,az,gx,gy,gz log at 1 kHz: an accelerometer (g) and a gyroscope (dps) in one file."""
    rng = np.random.default_rng(4)
    with path.open("w") as f:
        f.write("t,ax,ay,az,gx,gy,gz\n")
        for start in range(0, rows, 500_000):
            n = min(500_000, rows - start)
            t = np.arange(start, start + n) / 1000.0
            acc = rng.normal([0.01, -0.02, 1.01], 0.01, size=(n, 3))
            gyro = rng.normal([0.5, -0.3, 0.2], 0.05, size=(n, 3))
            fmt = ["%.3f", "%.6f", "%.6f", "%.6f", "%.4f", "%.4f", "%.4f"]
            np.savetxt(f, np.column_stack([t, acc, gyro]), fmt=fmt, delimiter=",")


def write_wide(path: Path, columns: int, rows: int) -> None:
    """A capture of ``columns`` columns, x,y,z first (100,000 columns, 10 rows: 3 MB)."""
    with path.open("w") as f:
        f.write(",".join(["ax", "ay", "az", *(f"c{i}" for i in range(columns - 3))]) + "\n")
        row = ",".join(["0.5", "0.25", "1.0", *("1" for _ in range(columns - 3))]) + "\n"
        f.write(row * rows)


def gyro_calibration(cal: Path, out: Path) -> None:
    """The accelerometer's calibration recorded for columns gx,gy,gz (a second sensor to apply)."""
    import json

    data = json.loads(cal.read_text())
    data["columns"], data["sensor"] = ["gx", "gy", "gz"], "gyroscope"
    out.write_text(json.dumps(data))


def write_tumble(path: Path, rows: int) -> None:
    """A 1 kHz t,x,y,z session turned from face to face: 15 s still, 5 s moving, repeated
    (written a million rows at a time with pyarrow: 20M rows in seconds)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(2)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    with path.open("wb") as f:
        f.write(b"t,x,y,z\n")
        for start in range(0, rows, 1_000_000):
            n = min(1_000_000, rows - start)
            t = np.arange(start, start + n) / 1000.0
            phase = t % 20.0
            k = (t // 20.0).astype(int)
            w = np.clip((phase - 15.0) / 5.0, 0, 1)[:, None]  # 0 while still, 0 -> 1 while turning
            g = (1 - w) * faces[k % 6] + w * faces[(k + 1) % 6] + np.sin(np.pi * w) * 0.3 * rng.normal(size=(n, 3))
            xyz = np.round(g + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.002, size=(n, 3)), 6)
            table = pa.table({"t": np.round(t, 3), "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})
            pcsv.write_csv(table, f, pcsv.WriteOptions(include_header=False))


def write_session(path: Path, rows: int, still: float = 20.0, turn: float = 3.0) -> None:
    """A 1 kHz t,ax,ay,az session in g: ``still`` seconds on a face, ``turn`` seconds turning to
    the next, the six faces over and over (5M rows: 183 MB; written with pyarrow, a million rows
    at a time)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(2)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    cycle = still + turn
    with path.open("wb") as f:
        f.write(b"t,ax,ay,az\n")
        for start in range(0, rows, 1_000_000):
            n = min(1_000_000, rows - start)
            t = np.arange(start, start + n) / 1000.0
            k = (t // cycle).astype(int)
            w = np.clip((t % cycle - still) / turn, 0, 1)[:, None]  # 0 while still, 0 -> 1 while turning
            g = (1 - w) * faces[k % 6] + w * faces[(k + 1) % 6] + np.sin(np.pi * w) * 0.3 * rng.normal(size=(n, 3))
            xyz = np.round(g + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.002, size=(n, 3)), 6)
            table = pa.table({"t": np.round(t, 3), "ax": xyz[:, 0], "ay": xyz[:, 1], "az": xyz[:, 2]})
            pcsv.write_csv(table, f, pcsv.WriteOptions(include_header=False))


def write_orientations(path: Path, rows: int, still: float = 20.0, turn: float = 3.0) -> None:
    """A 100 Hz t,ax,ay,az log in g turned by hand through many orientations: ``still`` seconds
    at rest in a random direction (uniform on the sphere), ``turn`` seconds turning to the next
    (5M rows: 2,174 still blocks, 186 MB; written with pyarrow, a million rows at a time)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(4)
    cycle, rate = still + turn, 100.0
    count = int(rows / rate // cycle) + 2
    ups = rng.normal(size=(count, 3))
    ups /= np.linalg.norm(ups, axis=1)[:, None]
    with path.open("wb") as f:
        f.write(b"t,ax,ay,az\n")
        for start in range(0, rows, 1_000_000):
            n = min(1_000_000, rows - start)
            t = np.arange(start, start + n) / rate
            k = (t // cycle).astype(int)
            w = np.clip((t % cycle - still) / turn, 0, 1)[:, None]  # 0 while still, 0 -> 1 while turning
            g = (1 - w) * ups[k] + w * ups[k + 1]
            g /= np.maximum(np.linalg.norm(g, axis=1), 1e-9)[:, None]
            g += np.sin(np.pi * w) * 0.3 * rng.normal(size=(n, 3))
            gain = np.array([1.02, 0.98, 1.01])
            xyz = np.round(gain * g + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.002, size=(n, 3)), 6)
            table = pa.table({"t": np.round(t, 2), "ax": xyz[:, 0], "ay": xyz[:, 1], "az": xyz[:, 2]})
            pcsv.write_csv(table, f, pcsv.WriteOptions(include_header=False))


def written_apart(writer: str, path: Path, rows: int) -> None:
    """``writer`` (a function of this file) writes ``path`` in a process of its own: a child's peak
    memory (ru_maxrss) starts at the size of the process it was forked from, so the bench keeps
    small and the peaks measured are the commands' own."""
    code = f"import sys; sys.path.insert(0, {str(ROOT)!r}); from pathlib import Path; from tests import bench; "
    subprocess.run([sys.executable, "-c", code + f"bench.{writer}(Path({str(path)!r}), {rows})"], check=True)


def bench_pace(folder: Path) -> list[tuple[str, float, float, str]]:
    """segment and solve --log of 5M- and 20M-row logs of both shapes (a few faces: write_session;
    thousands of orientations: write_orientations) against POLARS_BLOCKS on the same file, taking
    turns (five runs each, the median), each with both peak memories; and segment -d (every
    block written) against segment alone."""
    found = []
    for millions in (5, 20):
        for shape, writer in (("faces", "write_session"), ("orient.", "write_orientations")):
            log = folder / f"pace{millions}M.csv"
            written_apart(writer, log, millions * 1_000_000)
            size = log.stat().st_size / 1e6
            script = [sys.executable, "-c", POLARS_BLOCKS, str(log)]
            segment = [*TUMBLECAL, "segment", "-q", str(log)]
            commands = (
                ("segment", segment),
                ("solve --log", [*TUMBLECAL, "solve", "-q", "--log", str(log), "-o", str(folder / "pace.json")]),
            )
            for what, argv in commands:
                (ours, rss), (base, base_rss) = paired(argv, script)
                note = f"peak {rss:.0f} MiB, polars {base_rss:.0f} MiB"
                found.append((f"{what} {shape} {millions}M ({size:.0f} MB)", ours, base, note))
            blocks = folder / "pace-blocks"
            (ours, rss), (base, _) = paired(
                [*segment, "-d", str(blocks)], segment, repeat=3, fresh=(blocks, folder / "no-such-file")
            )
            written = len(list(blocks.glob("*.csv"))) - 1
            note = f"vs segment; {written} blocks, peak {rss:.0f} MiB"
            found.append((f"segment -d {shape} {millions}M", ours, base, note))
            log.unlink()
    return found


def write_units(folder: Path, units: int) -> None:
    """``units`` folders of x.csv y.csv z.csv, 1000 samples each at 100 Hz, each unit with its own
    offsets and gains (in g), like a production lot."""
    rng = np.random.default_rng(3)
    t = np.arange(1000) / 100.0
    for k in range(units):
        offset = rng.normal(0, 0.02, 3)
        gain = 1 + rng.normal(0, 0.01, 3)
        unit = folder / f"SN{k:05d}"
        unit.mkdir(parents=True)
        for axis, name in enumerate("xyz"):
            mean = offset + gain * np.eye(3)[axis]
            xyz = rng.normal(mean, 0.003, size=(1000, 3))
            with (unit / f"{name}.csv").open("w") as f:
                f.write("t,ax,ay,az\n")
                np.savetxt(f, np.column_stack([t, xyz]), fmt=["%.2f", "%.6f", "%.6f", "%.6f"], delimiter=",")


def timed(argv: list[str], repeat: int, fresh: Path) -> float:
    """Best wall time of ``argv`` run ``repeat`` times, ``fresh`` removed before each run."""
    import shutil

    best = float("inf")
    for _ in range(repeat):
        shutil.rmtree(fresh, ignore_errors=True)
        start = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - start)
    return best


def write_still(path: Path, rows: int) -> None:
    """A still x,y,z capture (white noise and a slow random walk), 5 decimals, written with pyarrow."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(2)
    walk = np.zeros(3)
    with pcsv.CSVWriter(str(path), pa.schema([(a, pa.float64()) for a in "xyz"])) as writer:
        for start in range(0, rows, 1_000_000):
            n = min(1_000_000, rows - start)
            steps = np.cumsum(rng.normal(0, 1e-5, (n, 3)), axis=0) + walk
            walk = steps[-1]
            xyz = np.round(rng.normal([0.01, -0.02, 1.01], 0.01, (n, 3)) + steps, 5)
            writer.write_table(pa.table({a: xyz[:, i] for i, a in enumerate("xyz")}))


OADEV = """
import sys, pandas, allantools
d = pandas.read_csv(sys.argv[1])
for c in "xyz":
    allantools.oadev(d[c].to_numpy(), rate=200.0, data_type="freq", taus="octave")
"""


def bench_noise(folder: Path) -> tuple[list[tuple[str, float, float, str]], dict[float, float]]:
    """noise on 4M and 10M samples against allantools' oadev (read with pandas) in the same run,
    and noise's peak memory at 2.5M and 10M samples."""
    rows, memory = [], {}
    for millions in (2.5, 4, 10):
        still = folder / f"still{millions}M.csv"
        written_apart("write_still", still, int(millions * 1_000_000))
        argv = [*TUMBLECAL, "noise", "-q", "--rate", "200", str(still)]
        if millions in (4, 10):
            (ours, rss), (base, base_rss) = paired(argv, [sys.executable, "-c", OADEV, str(still)], repeat=3)
            size = still.stat().st_size / 1e6
            note = f"{size:.0f} MB; peak {rss:.0f} MiB, allantools {base_rss:.0f} MiB"
            rows.append((f"noise {millions}M samples", ours, base, note))
        else:
            ours, rss = run(argv, repeat=2)
        memory[millions] = rss
        still.unlink()
    return rows, memory


def bench_logs(folder: Path) -> list[tuple[str, float, float, str]]:
    """segment (writing every block) and solve --log of a 20M-row session against
    pandas.read_csv of it, each with its peak memory."""
    session = folder / "session20M.csv"
    write_tumble(session, 20_000_000)
    size = session.stat().st_size / 1e6
    base, base_rss = run([sys.executable, "-c", f"import pandas; pandas.read_csv({str(session)!r})"], repeat=2)
    out = folder / "blocks20M"
    ours, rss = run([*TUMBLECAL, "segment", "-q", str(session), "-d", str(out)], repeat=2, fresh=out)
    blocks = len(list(out.glob("*.csv"))) - 1
    found = [
        (f"segment 20M rows ({size:.0f} MB)", ours, base, f"{blocks} blocks; peak {rss:.0f} MiB, pandas {base_rss:.0f}")
    ]
    cal = folder / "log-cal.json"
    ours, rss = run([*TUMBLECAL, "solve", "-q", "--log", str(session), "-o", str(cal)], repeat=2)
    found.append(("solve --log 20M rows", ours, base, f"peak {rss:.0f} MiB, pandas {base_rss:.0f}"))
    session.unlink()
    return found


#: Reading one stream of a ULog, as tumblecal does and as PX4's parser does: python -c X log.ulg
ULOG_OURS = """
import sys
from tumblecal_cli.io.csv import readings
from tumblecal_cli.io.readspec import ReadSpec
log = readings.read_log(sys.argv[1], ReadSpec(stream="sensor_accel:0"))
assert len(log.values) > 0
print(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")))
"""
ULOG_PYULOG = """
import sys
import numpy as np
from pyulog import ULog
data = ULog(sys.argv[1], message_name_filter_list=["sensor_accel"]).get_dataset("sensor_accel", 0).data
values = np.column_stack([data["x"], data["y"], data["z"]]).astype(float)
print(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")))
"""
#: PX4 1.12's sensor_accel and sensor_gyro formats (tests/ulog_writer.py, from a real log).
ULOG_FORMATS = {
    "sensor_accel": "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;"
    "float temperature;uint32_t error_count;uint8_t[3] clip_counter;uint8_t samples;uint8_t[4] _padding0;",
    "sensor_gyro": "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;"
    "float temperature;uint32_t error_count;uint8_t samples;uint8_t[7] _padding0;",
}


def write_ulog(path: Path, rows: int) -> None:
    """A PX4 ULog of ``rows`` samples of sensor_accel and sensor_gyro, two instances each at 1 kHz,
    in time order, a sync marker every 1000 samples (the format of tests/ulog_writer.py)."""
    import struct

    def message(kind: str, body: bytes) -> bytes:
        return struct.pack("<HB", len(body), ord(kind)) + body

    head = b"ULog\x01\x12\x35\x01" + bytes(8) + message("B", bytes(40))
    head += b"".join(message("F", f"{name}:{fmt}".encode()) for name, fmt in ULOG_FORMATS.items())
    streams = [("sensor_accel", 0), ("sensor_accel", 1), ("sensor_gyro", 0), ("sensor_gyro", 1)]
    head += b"".join(message("A", struct.pack("<BH", i, 20 + k) + n.encode()) for k, (n, i) in enumerate(streams))
    rng = np.random.default_rng(1)
    t = np.arange(rows, dtype=np.uint64) * 1000 + 10_000_000
    parts = []
    for k, (name, _) in enumerate(streams):
        tail = 4 if name == "sensor_accel" else 1  # the trailing padding is not logged
        fields = [("size", "<u2"), ("kind", "u1"), ("id", "<u2"), ("t", "<u8"), ("ts", "<u8"), ("dev", "<u4")]
        layout = np.dtype([*fields, ("xyz", "<f4", 3), ("temp", "<f4"), ("err", "<u4"), ("tail", "u1", tail)])
        one = np.zeros(rows, dtype=layout)
        one["size"], one["kind"], one["id"] = layout.itemsize - 3, ord("D"), 20 + k
        one["t"], one["ts"], one["temp"] = t + 3 * k + 150, t + 3 * k, 30.0
        one["xyz"] = rng.normal(0, 0.05, (rows, 3)) + np.array([0.0, 0.0, -9.81])
        parts.append(one.view(np.uint8).reshape(rows, -1))
    body = np.concatenate(parts, axis=1)
    sync = message("S", b"\x2f\x73\x13\x20\x25\x0c\xbb\x12")
    with open(path, "wb") as f:
        f.write(head)
        for i in range(0, rows, 1000):
            f.write(body[i : i + 1000].tobytes() + sync)


def _peak(argv: list[str], repeat: int = 3) -> tuple[float, float]:
    """Best wall time of ``argv`` and the peak memory it prints (its VmHWM, MiB: a child's
    ru_maxrss starts at its parent's size, which here holds the log it wrote)."""
    best, peak = float("inf"), 0.0
    for _ in range(repeat):
        start = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True, check=True)
        best = min(best, time.perf_counter() - start)
        peak = max(peak, int(done.stdout.split()[-2]) / 1024)
    return best, peak


def bench_ulog(folder: Path) -> list[tuple[str, float, float, str]]:
    """Reading one stream of a 100 MB ULog against pyulog loading that topic, each a fresh process."""
    log = folder / "log100M.ulg"
    write_ulog(log, 510_000)
    size = log.stat().st_size / 1e6
    ours, rss = _peak([sys.executable, "-c", ULOG_OURS, str(log)])
    base, base_rss = _peak([sys.executable, "-c", ULOG_PYULOG, str(log)])
    logs, _ = run([*TUMBLECAL, "logs", str(log)], repeat=2)
    note = f"{size / ours:.0f} MB/s; peak {rss:.0f} MiB, pyulog {base_rss:.0f} MiB; tumblecal logs {logs:.2f} s"
    log.unlink()
    return [(f"ULog stream, {size:.0f} MB", ours, base, note)]


#: Reading one stream of a DataFlash log, as tumblecal does and as pymavlink does: python -c X log.bin
DATAFLASH_OURS = ULOG_OURS.replace('stream="sensor_accel:0"', 'stream="IMU:0"')
DATAFLASH_PYMAVLINK = """
import sys
import numpy as np
from pymavlink import DFReader
with DFReader.DFReader_binary(sys.argv[1]) as log:
    rows = []
    while (m := log.recv_match(type="IMU")) is not None:
        if m.I == 0:
            rows.append((m.TimeUS, m.AccX, m.AccY, m.AccZ, m.T))
values = np.array(rows)
print(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")))
"""

#: Reading one topic of a ROS bag, as tumblecal does and as rosbags' own reader does: python -c X bag
ROS_OURS = ULOG_OURS.replace("sensor_accel:0", "/imu/data_raw")
ROS_ROSBAGS = """
import sys
from pathlib import Path
import numpy as np
from rosbags.highlevel import AnyReader
with AnyReader([Path(sys.argv[1])]) as reader:
    found = [c for c in reader.connections if c.topic == "/imu/data_raw"]
    rows = []
    for c, _, data in reader.messages(connections=found):
        m = reader.deserialize(data, c.msgtype)
        a = m.linear_acceleration
        rows.append((m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, a.x, a.y, a.z))
values = np.array(rows)
assert len(values) > 0
print(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")))
"""


def write_dataflash(path: Path, rows: int) -> None:
    """An ArduPilot DataFlash log of ``rows`` time steps of IMU, ACC and GYR, two instances each
    at 1 kHz (the format of tests/dataflash_writer.py, INS_ACC* at their defaults: raw)."""
    sys.path.insert(0, str(ROOT))
    from tests import dataflash_writer as writer

    t = np.arange(rows, dtype=np.int64) * 1000 + 10_000_000
    rng = np.random.default_rng(1)
    acc = rng.normal(0, 0.05, (rows, 3)) + np.array([0.0, 0.0, -9.81])
    gyr = rng.normal(0, 0.01, (rows, 3))
    parts = []
    for k in range(2):
        parts.append(writer.imu(t + 3 * k, acc, np.full(rows, 30.0), k, gyr))
        xyz = {"AccX": acc[:, 0], "AccY": acc[:, 1], "AccZ": acc[:, 2]}
        parts.append(writer.records("ACC", rows, TimeUS=t + 3 * k + 100, I=k, SampleUS=t + 3 * k, **xyz))
        xyz = {"GyrX": gyr[:, 0], "GyrY": gyr[:, 1], "GyrZ": gyr[:, 2]}
        parts.append(writer.records("GYR", rows, TimeUS=t + 3 * k + 100, I=k, SampleUS=t + 3 * k, **xyz))
    path.write_bytes(writer.header(writer.identity(2), 9_000_000) + writer.frames(parts))


def bench_dataflash(folder: Path) -> list[tuple[str, float, float, str]]:
    """Reading one stream of a 100 MB DataFlash log against pymavlink reading that message type,
    each a fresh process (pymavlink once: it takes a minute or more)."""
    log = folder / "log100M.bin"
    write_dataflash(log, 424_000)
    size = log.stat().st_size / 1e6
    ours, rss = _peak([sys.executable, "-c", DATAFLASH_OURS, str(log)])
    base, base_rss = _peak([sys.executable, "-c", DATAFLASH_PYMAVLINK, str(log)], repeat=1)
    logs, _ = run([*TUMBLECAL, "logs", str(log)], repeat=2)
    note = f"{size / ours:.0f} MB/s; peak {rss:.0f} MiB, pymavlink {base_rss:.0f} MiB; tumblecal logs {logs:.2f} s"
    log.unlink()
    return [(f"DataFlash stream, {size:.0f} MB", ours, base, note)]


def write_bag(path: Path, kind: str, rows: int) -> None:
    """A bag (kind ros1: a ROS 1 bag; mcap: a ROS 2 bag in MCAP storage) of two sensor_msgs/Imu
    topics at 1 kHz, ``rows`` messages each, in time order: messages laid out with numpy as each
    ROS version serializes them (a frame_id of 8 characters) and written by rosbags' writers."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    cdr = kind != "ros1"
    head = [("enc", "<u4")] if cdr else [("seq", "<u4")]
    frame = [("frame", "S9"), ("pad", "S3")] if cdr else [("frame", "S8")]
    layout = np.dtype([*head, ("sec", "<u4"), ("nsec", "<u4"), ("length", "<u4"), *frame, ("block", "<f8", 37)])
    rng = np.random.default_rng(2)
    t = np.arange(rows, dtype=np.int64) * 1_000_000 + 1_700_000_000_000_000_000
    topics = ["/imu/data_raw", "/imu2/data_raw"]
    msgs = []
    for k in range(len(topics)):
        one = np.zeros(rows, dtype=layout)
        one[head[0][0]] = 0x100 if cdr else np.arange(rows)
        one["sec"], one["nsec"] = np.divmod(t + k * 1000, 1_000_000_000)
        one["length"], one["frame"] = (9, b"imu_link") if cdr else (8, b"imu_link")
        one["block"][:, 25:28] = rng.normal(0, 0.05, (rows, 3)) + np.array([0.0, 0.0, 9.81])
        one["block"][:, 13:16] = rng.normal(0, 0.001, (rows, 3))
        msgs.append(one.view(np.uint8).reshape(rows, -1))
    size = layout.itemsize
    if not cdr:
        w1 = Writer1(path)
        with w1:
            conns = [
                w1.add_connection(n, "sensor_msgs/msg/Imu", typestore=get_typestore(Stores.ROS1_NOETIC)) for n in topics
            ]
            for i in range(rows):
                for k, c in enumerate(conns):
                    w1.write(c, int(t[i]) + k * 1000, msgs[k][i].tobytes())
        return
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w2:
        store = get_typestore(Stores.ROS2_HUMBLE)
        conns2 = [w2.add_connection(n, "sensor_msgs/msg/Imu", typestore=store) for n in topics]
        for i in range(rows):
            for k, c2 in enumerate(conns2):
                w2.write(c2, int(t[i]) + k * 1000, msgs[k][i].tobytes()[:size])


def bench_ros(folder: Path) -> list[tuple[str, float, float, str]]:
    """Reading one topic of a 100 MB bag (ROS 1, ROS 2 in MCAP) against rosbags' AnyReader and
    deserialize of that topic, each a fresh process."""
    import shutil

    found = []
    for kind, what in (("ros1", "ROS 1 bag"), ("mcap", "ROS 2 MCAP bag")):
        bag = folder / ("bag100M.bag" if kind == "ros1" else "bag100M")
        write_bag(bag, kind, 155_000)
        size = sum(p.stat().st_size for p in ([bag] if bag.is_file() else bag.iterdir())) / 1e6
        ours, rss = _peak([sys.executable, "-c", ROS_OURS, str(bag)])
        base, base_rss = _peak([sys.executable, "-c", ROS_ROSBAGS, str(bag)])
        logs, _ = run([*TUMBLECAL, "logs", str(bag)], repeat=2)
        note = f"{size / ours:.0f} MB/s; peak {rss:.0f} MiB, rosbags {base_rss:.0f} MiB; tumblecal logs {logs:.2f} s"
        found.append((f"{what} stream, {size:.0f} MB", ours, base, note))
        shutil.rmtree(bag) if bag.is_dir() else bag.unlink()
    return found


def bench_against(rev: str, folder: Path) -> list[tuple[str, float, float, str]]:
    """``make bench AGAINST=REV``: each command of this tree and of ``rev`` (its ``tumblecal_cli``
    taken out of git into ``folder``) taking turns, nine runs each, the median wall time of each:
    the figure that says whether a change made a command slower. Both run with the same Python
    and libraries; only the package differs (PYTHONPATH)."""
    import shutil
    import statistics

    base_root = folder / "against"
    base_root.mkdir()
    archive = subprocess.run(["git", "archive", rev, "tumblecal_cli"], cwd=ROOT, capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(base_root)], input=archive.stdout, check=True)
    import compileall

    compileall.compile_dir(str(base_root / "tumblecal_cli"), quiet=1)
    cal, log, session, still, units = (folder / n for n in ("cal.json", "1M.csv", "s.csv", "still.csv", "units"))
    poses = [str(ROOT / "sample_data" / f"{a}.csv") for a in "xyz"]
    subprocess.run([*TUMBLECAL, "solve", "-q", "--poses", *poses, "-o", str(cal)], check=True)
    write_log(log, 1_000_000)
    write_tumble(session, 600_000)
    write_still(still, 1_000_000)
    write_units(units, 20)
    out = folder / "out"
    commands = {
        "--help": ["--help"],
        "solve --help": ["solve", "--help"],
        "solve 3 poses": ["solve", "--poses", *poses, "-o", str(out / "c.json")],
        "solve -q 3 poses": ["solve", "-q", "--poses", *poses, "-o", str(out / "c.json")],
        "apply 1M rows": ["apply", "-q", "--cal", str(cal), str(log), "-o", str(out / "o.csv")],
        "segment 600k rows": ["segment", "-q", str(session), "-d", str(out / "poses")],
        "solve --log 600k rows": ["solve", "-q", "--log", str(session), "-o", str(out / "l.json")],
        "noise 1M samples": ["noise", "-q", "--rate", "200", str(still)],
        "show": ["show", str(cal)],
        "check": ["check", str(cal), "--max-offset", "0.1"],
        "export c-header": ["export", "--format", "c-header", str(cal), "-o", str(out / "c.h")],
        "verify": ["verify", "--cal", str(cal), *poses],
        "batch 20 units": ["batch", "-q", str(units), "-d", str(out / "cals")],
    }

    def once(argv: list[str], pythonpath: Path) -> float:
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir()
        env = {**os.environ, "PYTHONPATH": str(pythonpath), "PYTHONSAFEPATH": "1"}  # not the working folder's
        start = time.perf_counter()
        done = subprocess.run([*TUMBLECAL, *argv], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        if done.returncode not in (0, 1):
            raise SystemExit(f"bench: tumblecal {' '.join(argv)} failed: {done.stderr.decode()}")
        return time.perf_counter() - start

    for tree in (ROOT, base_root):  # each run imports its own tree's package, not the working folder's
        where = subprocess.run(
            [sys.executable, "-c", "import tumblecal_cli; print(tumblecal_cli.__file__)"],
            env={**os.environ, "PYTHONPATH": str(tree), "PYTHONSAFEPATH": "1"},
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        if not Path(where.strip()).is_relative_to(tree):
            raise SystemExit(f"bench: the package of {tree} is not the one imported ({where.strip()})")
    rows = []
    for what, argv in commands.items():
        ours, base = [], []
        for _ in range(9):
            ours.append(once(argv, ROOT))
            base.append(once(argv, base_root))
        rows.append((what, statistics.median(ours), statistics.median(base), f"vs {rev}"))
    return rows


def print_against(rev: str) -> None:
    """The lines of ``bench_against``: each command's median wall time here and at ``rev``."""
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        rows = bench_against(rev, Path(tmp))
    print(f"tumblecal bench against {rev}, {date.today()}, load average {load:.1f}-{os.getloadavg()[0]:.1f}")
    print(f"{'what':<28} {'this tree':>10} {rev[:10]:>10} {'ratio':>7}")
    for what, ours, base, _ in rows:
        print(f"{what:<28} {ours:>9.3f}s {base:>9.3f}s {ours / base:>6.2f}x")


def cpu_model() -> str:
    """The processor's name, where the system says it (Linux)."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return platform.processor() or "processor unknown"
    return next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "processor unknown")


def compiled() -> None:
    """The package's modules compiled to bytecode first, as an install leaves them (where the
    environment sets PYTHONDONTWRITEBYTECODE each run would compile every module again)."""
    import compileall

    compileall.compile_dir(str(ROOT / "tumblecal_cli"), quiet=1)


def bench_record(solve_argv: list[str], folder: Path) -> tuple[str, float, float, str]:
    """solve --record into a SQLite file against the same solve without (issue: at most 20 ms more);
    each recorded run a new serial, so each adds a record."""
    db = folder / "records.db"
    subprocess.run([*solve_argv, "--record", str(db)], check=True)  # the database made first
    serials = iter(range(1_000_000))
    recorded: list[float] = []
    plain: list[float] = []
    for _ in range(9):  # taking turns, the best of each: a busy spell falls on both
        plain.append(run(solve_argv, repeat=1)[0])
        recorded.append(run([*solve_argv, "--serial", f"B{next(serials)}", "--record", str(db)], repeat=1)[0])
    ours, base = min(recorded), min(plain)
    return ("solve --record (SQLite)", ours, base, f"{(ours - base) * 1e3:+.0f} ms for the record (at most 20)")


def main() -> None:
    rows: list[tuple[str, float, float, str]] = []
    compiled()
    if sys.argv[1:] == ["pace"]:  # the lines of the polars script's pace, and noise against allantools
        load = os.getloadavg()[0]
        with tempfile.TemporaryDirectory() as tmp:
            rows = bench_pace(Path(tmp))
            noise_rows, peak = bench_noise(Path(tmp))
        machine = f"{platform.node()} ({os.cpu_count()} cores, {cpu_model()}, Python {platform.python_version()})"
        print(f"tumblecal bench pace, {date.today()}, {machine}, load average {load:.1f}-{os.getloadavg()[0]:.1f}")
        for what, ours, base, note in rows + noise_rows:
            print(f"{what:<28} {ours:>9.2f}s {base:>9.2f}s {ours / base:>6.2f}x  {note}")
        what = "noise peak memory 10M / 2.5M"
        print(f"{what:<28} {peak[10]:>8.0f}Mi {peak[2.5]:>8.0f}Mi {peak[10] / peak[2.5]:>6.2f}x")
        return
    if sys.argv[1:] in (["ulog"], ["dataflash"], ["ros"]):
        with tempfile.TemporaryDirectory() as tmp:
            bench = {"ulog": bench_ulog, "dataflash": bench_dataflash, "ros": bench_ros}[sys.argv[1]]
            rows = bench(Path(tmp))
        for what, ours, base, note in rows:
            print(f"{what:<28} {ours:>9.2f}s {base:>9.2f}s {ours / base:>6.2f}x  {note}")
        return
    if sys.argv[1:2] == ["against"]:  # make bench AGAINST=REV: every command, this tree and REV in turns
        print_against(sys.argv[2])
        return
    if sys.argv[1:] == ["noise"]:
        with tempfile.TemporaryDirectory() as tmp:
            rows, peak = bench_noise(Path(tmp))
        for what, ours, base, note in rows:
            print(f"{what:<28} {ours:>9.2f}s {base:>9.2f}s {ours / base:>6.2f}x  {note}")
        print(
            f"{'noise peak memory 10M / 2.5M':<28} {peak[10]:>8.0f}Mi {peak[2.5]:>8.0f}Mi {peak[10] / peak[2.5]:>6.2f}x"
        )
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cal = folder / "cal.json"
        poses = [str(ROOT / "sample_data" / f"{a}.csv") for a in "xyz"]
        subprocess.run([*TUMBLECAL, "solve", "-q", "--poses", *poses, "-o", str(cal)], check=True)
        memory: dict[object, float] = {}
        out = str(folder / "out.csv")
        for millions in (1, 4, 20):
            log = folder / f"log{millions}M.csv"
            write_log(log, millions * 1_000_000)
            size = log.stat().st_size / 1e6
            (ours, rss), (base, base_rss) = paired(
                [*TUMBLECAL, "apply", "-q", "--cal", str(cal), str(log), "-o", out],
                [sys.executable, "-c", POLARS_APPLY, str(log), out, str(cal)],
            )
            memory[millions] = rss
            note = f"{size / ours:.0f} MB/s, peak {rss:.0f} MiB (polars {base_rss:.0f})"
            rows.append((f"apply {millions}M rows ({size:.0f} MB)", ours, base, note))
            if millions == 20:  # each run into a new file: no earlier output's pages to replace
                new, new_base = folder / "new.csv", folder / "new-polars.csv"
                (ours, rss), (base, _) = paired(
                    [*TUMBLECAL, "apply", "-q", "--cal", str(cal), str(log), "-o", str(new)],
                    [sys.executable, "-c", POLARS_APPLY, str(log), str(new_base), str(cal)],
                    fresh=(new, new_base),
                )
                rows.append(("apply 20M rows, new output", ours, base, "the output removed before each run (both)"))
                new.unlink(missing_ok=True)
                new_base.unlink(missing_ok=True)
            if millions == 4:
                base, _ = run([sys.executable, "-c", f"import pandas; pandas.read_csv({str(log)!r})"])
                rows.append(("apply 4M rows vs pandas", ours, base, "pandas.read_csv only reads"))
            if millions != 1:
                log.unlink()
        imu, gyro = folder / "imu4M.csv", folder / "gyro.json"
        write_imu(imu, 4_000_000)
        gyro_calibration(cal, gyro)
        (ours, rss), (base, _) = paired(
            [*TUMBLECAL, "apply", "-q", "--cal", str(cal), "--cal", str(gyro), str(imu), "-o", out],
            [sys.executable, "-c", POLARS_APPLY, str(imu), out, str(cal), str(gyro)],
        )
        size = imu.stat().st_size / 1e6
        rows.append((f"apply 2 sensors, 4M ({size:.0f} MB)", ours, base, f"{size / ours:.0f} MB/s, peak {rss:.0f} MiB"))
        imu.unlink()
        wide = folder / "wide.csv"
        write_wide(wide, 100_000, 10)
        _, memory["wide"] = run([*TUMBLECAL, "apply", "-q", "--cal", str(cal), str(wide), "-o", out])
        rows.append(thermal_bench(folder, cal))
        solve_argv = [*TUMBLECAL, "solve", "-q", "--poses", *poses, "-o", str(folder / "c.json")]
        ours, _ = run(solve_argv, repeat=5)
        base, _ = run([sys.executable, "-c", "import pandas, numpy"], repeat=5)
        rows.append(("solve 3 poses (start-up)", ours, base, "vs import pandas, numpy"))
        rows.append(bench_record(solve_argv, folder))
        session = folder / "session.csv"
        write_tumble(session, 600_000)
        base, _ = run([sys.executable, "-c", f"import pandas; pandas.read_csv({str(session)!r})"])
        ours, _ = run([*TUMBLECAL, "segment", "-q", str(session), "-d", str(folder / "poses")])
        blocks = len(list((folder / "poses").glob("*.csv"))) - 1
        rows.append(("segment 600k rows (10 min)", ours, base, f"{blocks} blocks written"))
        session.unlink()
        rows += bench_logs(folder)
        rows += bench_pace(folder)
        units = folder / "units"
        write_units(units, 200)
        loop = (  # what a station script does today: one process per unit
            'mkdir -p "$2"; for d in "$1"/*/; do u=$(basename "$d"); '
            '"$3" solve -q --poses "$d/x.csv" "$d/y.csv" "$d/z.csv" --serial "$u" -o "$2/$u.json"; done'
        )
        script = str(Path(sys.executable).parent / "tumblecal")
        base = timed(["bash", "-c", loop, "loop", str(units), str(folder / "loop"), script], 1, folder / "loop")
        for jobs in (1, 2):
            argv = [*TUMBLECAL, "batch", "-q", str(units), "-d", str(folder / "cals"), "--jobs", str(jobs)]
            ours = timed(argv, 3, folder / "cals")
            rows.append((f"batch 200 units, --jobs {jobs}", ours, base, f"{base / ours:.0f}x the units/s of the loop"))
        noise_rows, noise_memory = bench_noise(folder)
        rows += noise_rows
        rows += bench_ulog(folder)
        rows += bench_dataflash(folder)
        rows += bench_ros(folder)
    machine = f"{platform.node()} ({os.cpu_count()} cores, Python {platform.python_version()})"
    print(f"tumblecal bench, {date.today()}, {machine}")
    print(f"{'what':<28} {'tumblecal':>10} {'baseline':>10} {'ratio':>7}  notes")
    for what, ours, base, note in rows:
        print(f"{what:<28} {ours:>9.2f}s {base:>9.2f}s {ours / base:>6.2f}x  {note}")
    for what, key in (("apply peak memory 20M / 1M", 20), ("apply 100k columns / 1M rows", "wide")):
        print(f"{what:<28} {memory[key]:>8.0f}Mi {memory[1]:>8.0f}Mi {memory[key] / memory[1]:>6.2f}x")
    peak = noise_memory
    print(f"{'noise peak memory 10M / 2.5M':<28} {peak[10]:>8.0f}Mi {peak[2.5]:>8.0f}Mi {peak[10] / peak[2.5]:>6.2f}x")
    print("baselines: apply vs the polars script in tests/bench.py (scan_csv -> M (v - b) -> sink_csv)")
    print("           apply thermal vs apply of the same capture with the calibration without its thermal block")
    print("           solve vs python -c 'import pandas, numpy'")
    print("           segment, solve --log vs python -c 'import pandas; pandas.read_csv(f)' of the same log")
    print("           segment, solve --log 5M/20M vs the polars script of the still blocks (POLARS_BLOCKS)")
    print("           batch vs a bash loop of 'tumblecal solve' per unit (200 units x 3 poses x 1000 samples)")
    print("           noise vs pandas.read_csv + allantools.oadev of each axis (octave taus), the same file")
    print("           ULog stream vs pyulog.ULog(f, message_name_filter_list=['sensor_accel']) of the same log")
    print("           DataFlash stream vs pymavlink DFReader_binary(f) and recv_match(type='IMU') of the same log")
    print("           ROS bag stream vs rosbags' AnyReader.messages + deserialize of that topic, the same bag")


if __name__ == "__main__":
    main()
