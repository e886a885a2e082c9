"""`make same AGAINST=REV`: whether a change left every command's output as it was.

Not a test (pytest does not collect it). Runs each command of COMMANDS (every command of the
command line on the real captures of tests/data and sample_data) with git revision REV's
`tumblecal_cli` (taken out of git into a temporary folder), then with this tree's, the same Python
and libraries and the same environment, and compares what they did:

    exit code   equal
    stderr      equal after normalising each tree's folder to <ROOT> and temporary file names to <TMP>
    stdout      equal byte for byte (each tree's folder normalised)
    files       the same files, each equal byte for byte; a calibration (.json, .yaml, .yml holding
                format: tumblecal-calibration) as text without its top-level `created` (and `tool`,
                when both are "tumblecal <version>"); when that differs the line says whether the
                values (floats bit for bit) are the same, i.e. whether only the formatting changed

    python tests/same.py REV       # a line per difference, then "85 commands, 85 identical, 0 different"
    python tests/same.py --list    # the commands' names, in the order they run

Exit 0 when every command is identical, 1 when one is not, 2 on a usage error. Every command runs
from the repository's root (inputs and printed paths relative and the same for both trees) and
writes under one scratch folder, the same path for both trees, one after the other, so the paths
a command prints or records agree.
"""

from __future__ import annotations

import argparse
import compileall
import difflib
import glob
import gzip
import itertools
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from string import Template

import yaml

ROOT = Path(__file__).resolve().parent.parent
TUMBLECAL = [sys.executable, "-m", "tumblecal_cli"]
#: 2026-01-01T00:00:00Z: calibrations' `created`, batch's file names
SOURCE_DATE_EPOCH = "1767225600"

# Each command's arguments, split on blanks (no argument holds one). $O is the command's own output
# folder, $W/<name>/files another command's (the commands run in this order: later ones read earlier
# outputs), $IN the inputs derived from tests/data (make_inputs). An argument with a `*` is a glob
# (its matches sorted), and `<FILE` (last) is the command's stdin; stdin is otherwise empty.
XYZ = "sample_data/x.csv sample_data/y.csv sample_data/z.csv"
SIX = "sample_data/x.csv sample_data/xn.csv sample_data/y.csv sample_data/yn.csv sample_data/z.csv sample_data/zn.csv"
IMUCAL = " ".join(f"sample_data/imucal/{face}.csv" for face in ("xp", "xn", "yp", "yn", "zp", "zn"))
THERMAL = " ".join(f"sample_data/thermal/{face}.csv" for face in ("xp", "xn", "yp", "yn", "zp", "zn"))
SWEEPS = " ".join(
    f"{sign}{axis}=sample_data/thermal/sweep_{way}_{axis}{face}.csv"
    for axis in "xyz"
    for sign, way, face in (("+", "up", "p"), ("-", "down", "n"))
)
NCSU = "tests/data/ncsu_microstrain"
NCSU_X = "tests/data/ncsu_xplus_head.csv"
MOTION = " ".join(f"tests/data/ncsu_microstrain_motion/{face}.csv" for face in ("xplus", "xminus", "yplus", "yminus"))
MOTION += " tests/data/ncsu_microstrain_motion/zplus.csv tests/data/ncsu_microstrain_motion/zminus.csv"
LOGS = "tests/data/logs"
FERRARIS = f"{LOGS}/imucal_ferraris_session.csv.gz --rate 102.4"
LABELLED = (
    f"{LOGS}/imucal_annotated_session.csv.gz --rate 204.8 --pose-column part"
    " --pose-map x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z"
)
SIX_NCSU = (
    f"{NCSU_X} {NCSU}/xminus_head.csv {NCSU}/yplus_head.csv {NCSU}/yminus_head.csv"
    f" {NCSU}/zplus_head.csv {NCSU}/zminus_head.csv"
)
MAG = "tests/data/ckexplorer_mag/mag_every10.csv"
LOT = "sample_data/lot --limits sample_data/limits.yaml"
CALS = "$W/demo_solve_three/files/cal.json"

COMMANDS: list[tuple[str, list[str]]] = [
    (name, text.split())
    for name, text in [
        # -- sample_data: the README / Makefile demo
        ("demo_solve_three", f"solve --poses {XYZ} --limits sample_data/limits.yaml --serial demo-0001 -o $O/cal.json"),
        ("demo_apply", f"apply --cal {CALS} sample_data/capture.csv -o $O/corrected.csv"),
        (
            "demo_solve_imucal_yaml",
            f"solve --poses {IMUCAL} --reference 9.81 --units m/s^2 --input-units counts -o $O/imucal.yaml",
        ),
        # -- every accelerometer solver on sample_data
        ("s_one_pose", "solve --poses sample_data/z.csv --up +z --gain-tolerance 0.01 -o $O/cal.json"),
        ("s_one_pose_tilt", "solve --poses sample_data/z.csv --up +z --method one-pose-tilt -o $O/cal.json"),
        ("s_three_yaml_verbose", f"solve --poses {XYZ} --max-offset 0.04 -v -o $O/cal.yaml"),
        ("s_six_pose_json", f"solve --poses {SIX} --method six-pose --max-noise 0.5 --json -o $O/cal.json"),
        ("s_six_pose_diagonal", f"solve --poses {SIX} --method six-pose-diagonal --max-noise 0.5 -o $O/cal.json"),
        ("s_six_pose_magnitude", f"solve --poses {SIX} --method six-pose-magnitude --max-noise 0.5 -o $O/cal.json"),
        ("s_least_squares", f"solve --poses {SIX} --method least-squares --max-noise 0.5 -o $O/cal.json"),
        ("s_minmax", f"solve --poses {SIX} --method minmax --max-noise 0.5 -o $O/cal.json"),
        ("s_ellipsoid", f"solve --poses {SIX} --method ellipsoid --max-noise 0.5 -o $O/cal.json"),
        # -- real pose captures (tests/data)
        ("r_ncsu_one_pose", f"solve --poses {NCSU_X} --up +x -v -o $O/cal.json"),
        (
            "r_ncsu_three_pose",
            f"solve --poses +x={NCSU_X} +y={NCSU}/yplus_head.csv +z={NCSU}/zplus_head.csv -o $O/cal.json",
        ),
        ("r_ncsu_six_pose", f"solve --poses {SIX_NCSU} --max-noise 0.05 --json -o $O/cal.json"),
        (
            "r_ncsu_least_squares5",
            f"solve --poses +x={NCSU_X} -x={NCSU}/xminus_head.csv +y={NCSU}/yplus_head.csv -y={NCSU}/yminus_head.csv"
            f" +z={NCSU}/zplus_head.csv --method least-squares --max-noise 0.05 -o $O/cal.json",
        ),
        ("r_ncsu_motion_trim", f"solve --poses {MOTION} -v -o $O/cal.json"),
        (
            "r_ncsu_start_end",
            "solve --poses tests/data/ncsu_microstrain_motion/xplus.csv --up +x --start 10r --end 110r -o $O/cal.json",
        ),
        (
            "r_hassan_sphere_rows",
            "solve --poses tests/data/hassan_gnls/orient24.csv --rows-are-poses --method sphere -o $O/cal.json",
        ),
        (
            "r_hassan_verify_rows",
            "verify --cal $W/r_hassan_sphere_rows/files/cal.json tests/data/hassan_gnls/orient49.csv"
            " --rows-are-poses --json",
        ),
        (
            "r_xsens_counts_head",
            "solve --poses tests/data/xsens_acc_head.txt --up +z --no-header --nominal-offset 32768 --reference 3650"
            " -o $O/cal.json",
        ),
        ("r_stdin_one_pose", "solve --poses - --up +z --json -o $O/cal.json <sample_data/z.csv"),
        (
            "r_session4th_diagonal",
            "solve --log tests/data/imucal_session/session_every4th.csv --rate 25.6 --reference 9.81"
            " --method six-pose-diagonal -o $O/cal.json",
        ),
        # -- logs: solve --log, segment
        ("l_solve_ckexplorer", f"solve --log {LOGS}/ckexplorer_acc_log.csv -v -o $O/cal.json"),
        ("l_solve_hassan", f"solve --log {LOGS}/hassan_mobile_30orient.csv --json -o $O/cal.json"),
        ("l_solve_xsens_gz", f"solve --log {LOGS}/xsens_acc.txt.gz -o $O/cal.json"),
        ("l_solve_session_gz", f"solve --log {FERRARIS} --reference 9.81 -o $O/cal.json"),
        ("l_solve_labelled", f"solve --log {LABELLED} --reference 9.81 -o $O/cal.json"),
        ("l_segment_session_dir", f"segment {FERRARIS} -d $O/blocks"),
        ("l_segment_ckexplorer", f"segment {LOGS}/ckexplorer_acc_log.csv -v"),
        ("l_segment_xsens_dir", f"segment {LOGS}/xsens_acc.txt.gz -d $O/blocks -q"),
        (
            "l_solve_blocks_sphere",
            "solve --poses $W/l_segment_xsens_dir/files/blocks/block*.csv --method sphere -o $O/cal.json",
        ),
        (
            "l_verify_blocks",
            "verify --cal $W/l_solve_session_gz/files/cal.json $W/l_segment_session_dir/files/blocks/block*.csv",
        ),
        # -- gyroscope
        (
            "g_turns_ferraris",
            f"solve --sensor gyroscope --log {LABELLED} --turns x_rot=+x,y_rot=+y,z_rot=+z --turn-angle 360"
            " -o $O/cal.json",
        ),
        (
            "g_bias_still",
            "solve --sensor gyroscope --poses tests/data/xsens_gyro_still.txt --no-header --method gyro-bias"
            " -o $O/cal.json",
        ),
        ("g_xsens_acc_sphere", "solve --log $IN/xsens.csv --method sphere -o $O/acc.json"),
        (
            "g_rotations",
            "solve --sensor gyroscope --log $IN/xsens_first.csv --accel-cal $W/g_xsens_acc_sphere/files/acc.json"
            " --method rotations -o $O/gyro.json",
        ),
        (
            "g_verify_rotations",
            "verify --cal $W/g_rotations/files/gyro.json --log $IN/xsens_second.csv"
            " --accel-cal $W/g_xsens_acc_sphere/files/acc.json",
        ),
        (
            "g_verify_log",
            f"verify --cal $W/g_turns_ferraris/files/cal.json --log {LOGS}/imucal_annotated_session.csv.gz"
            " --accel-cal $W/l_solve_labelled/files/cal.json --rate 204.8 --json",
        ),
        # -- magnetometer
        ("m_ellipsoid", f"solve --sensor magnetometer --method ellipsoid --poses {MAG} -o $O/cal.json"),
        ("m_minmax", f"solve --sensor magnetometer --method minmax --poses {MAG} -o $O/cal.json"),
        (
            "m_auto_gauss",
            "solve --sensor magnetometer --units gauss --input-units gauss --reference 0.3"
            " --poses tests/data/ckexplorer_mag/acc_mag_every8.csv -v -o $O/cal.json",
        ),
        # -- noise
        ("n_acc_still", "noise tests/data/xsens_acc_still.txt --no-header -v"),
        ("n_gyro_still_json", "noise tests/data/xsens_gyro_still.txt --no-header --sensor gyroscope --json"),
        (
            "n_acc_cal_datasheet",
            "noise tests/data/xsens_acc_still.txt --no-header --cal $W/l_solve_xsens_gz/files/cal.json --taus 2 --json",
        ),
        (
            "n_kalibr_too_short",
            "noise tests/data/xsens_acc_still.txt --no-header --cal $W/l_solve_xsens_gz/files/cal.json"
            " --kalibr $O/imu.yaml",
        ),
        # -- thermal, current, apply
        ("t_base", f"solve --poses {THERMAL} -o $O/base.json"),
        ("t_thermal", f"thermal {SWEEPS} --cal $W/t_base/files/base.json -o $O/thermal.json"),
        (
            "t_thermal_order1_json",
            f"thermal {SWEEPS} --cal $W/t_base/files/base.json --order 1 --json -o $O/thermal1.yaml",
        ),
        (
            "t_apply_check",
            "apply --cal $W/t_thermal/files/thermal.json sample_data/thermal/check.csv -o $O/check_corrected.csv",
        ),
        ("ap_apply_stdout", f"apply --cal $W/r_ncsu_six_pose/files/cal.json {NCSU_X}"),
        (
            "ap_apply_two_cals_gz",
            "apply -c $W/l_solve_labelled/files/cal.json -c $W/g_turns_ferraris/files/cal.json"
            f" {LOGS}/imucal_annotated_session.csv.gz -o $O/corrected.csv",
        ),
        (
            "ap_apply_out_dir",
            f"apply --cal {CALS} sample_data/x.csv sample_data/yn.csv sample_data/capture.csv --out-dir $O/corrected",
        ),
        (
            "c_current",
            "current tests/data/ardupilot/spark404_mag_curr.csv --cal tests/data/ardupilot/spark404_mag_as_logged.json"
            " --current-column Curr -o $O/current.json",
        ),
        # -- export: every format
        ("e_c_header", "export $W/r_ncsu_six_pose/files/cal.json --format c-header -o $O/imu_cal.h"),
        ("e_registers", f"export {CALS} --format registers --lsb 0.000061 --bits 16 --gain-step 0.0005"),
        ("e_imucal_json", "export $W/l_solve_labelled/files/cal.json --format imucal-json -o $O/imucal_cal.json"),
        ("e_ros_yaml", "export $W/s_six_pose_json/files/cal.json --format ros-yaml -o $O/imu_calib.yaml"),
        ("e_matlab", "export $W/s_ellipsoid/files/cal.json --format matlab -o $O/cal.m"),
        ("e_ardupilot", f"export {CALS} --format ardupilot --instance 2 -o $O/imu.parm"),
        ("e_px4", f"export {CALS} --format px4 --instance 1 -o $O/imu.params"),
        ("e_ardupilot_mag", "export $W/m_auto_gauss/files/cal.json --format ardupilot"),
        ("e_px4_mag", "export $W/m_auto_gauss/files/cal.json -f px4 --instance 0"),
        ("e_ardupilot_thermal", "export $W/t_thermal/files/thermal.json --format ardupilot -o $O/tcal.parm"),
        ("e_px4_thermal", "export $W/t_thermal/files/thermal.json --format px4"),
        ("e_ardupilot_current", "export $W/c_current/files/current.json --format ardupilot"),
        ("e_c_header_gyro", "export $W/g_turns_ferraris/files/cal.json --format c-header --prefix imu_gyro"),
        # -- import, show, check, report, batch
        ("i_import_imucal", "import tests/data/imucal_session/example_cal.json -o $O/cal.json"),
        ("i_import_ros_roundtrip", "import $W/e_ros_yaml/files/imu_calib.yaml --from ros-yaml -o $O/cal.yaml"),
        ("x_show", f"show {CALS}"),
        ("x_show_json_yaml", "show $W/demo_solve_imucal_yaml/files/imucal.yaml --json"),
        ("x_check_limits_json", f"check {CALS} --limits sample_data/limits.yaml --json"),
        (
            "x_check_fail",
            "check $W/r_ncsu_six_pose/files/cal.json --max-offset 0.001 --max-gain-error 0.0001 -v",
        ),
        ("x_report_lot", f"report {LOT}"),
        ("x_report_lot_json", f"report {LOT} --max-drift offset=0.001,gain=0.0005 --min-cpk 1.33 --json"),
        ("x_batch_manifest", "batch sample_data/lot.csv --out-dir $O/cals --limits sample_data/limits.yaml --json"),
        # -- autopilot / robot logs
        ("a_logs_px4", "logs $IN/px4_small.ulg"),
        ("a_logs_ardupilot_json", "logs $IN/spark404_copter.bin --json"),
        ("a_logs_ros", "logs tests/data/ros/test1_cut.bag"),
        ("a_align_px4", "align $IN/px4_small.ulg --json"),
        (
            "a_mag_both",
            f"solve --sensor magnetometer --method ellipsoid --poses {LOGS}/ckexplorer_acc_mag_log.csv.gz"
            " -o $O/mag.json",
        ),
        (
            "a_align_acc_mag",
            "align --accel-cal $W/l_solve_ckexplorer/files/cal.json --mag-cal $W/a_mag_both/files/mag.json"
            f" {LOGS}/ckexplorer_acc_mag_log.csv.gz --window 10 --min-duration 10 --max-noise 0.1 -o $O/align.json",
        ),
        # -- a few rejections (exit 3) and input errors (exit 2)
        (
            "b_upside_down",
            "solve --poses tests/data/bad/upside_down_x.csv sample_data/y.csv sample_data/z.csv -o $O/cal.json",
        ),
        (
            "b_limits_unknown_key",
            f"solve --poses {XYZ} --limits tests/data/bad/limits_unknown_key.yaml -o $O/cal.json",
        ),
        ("b_show_truncated", "show tests/data/bad/cal_truncated.json"),
    ]
]


# -- running ---------------------------------------------------------------------------------


def make_inputs(folder: Path) -> None:
    """$IN: what the commands read that tests/data holds in another shape. The stream readers (logs,
    align) take no .gz: decompressed copies. imu_tk's Xsens accelerometer and gyroscope logs (one
    clock) joined as tests/test_rotations.py does, and its two halves, each with the header: hand
    turns need both sensors in one log."""
    folder.mkdir(parents=True)
    data = ROOT / "tests" / "data"

    def unzipped(name: str) -> bytes:
        return gzip.decompress((data / name).read_bytes())

    (folder / "px4_small.ulg").write_bytes(unzipped("px4/pyulog_sample_log_small.ulg.gz"))
    (folder / "spark404_copter.bin").write_bytes(unzipped("ardupilot/spark404_copter.bin.gz"))
    acc, gyro = (unzipped(f"logs/xsens_{sensor}.txt.gz").decode().split("\n") for sensor in ("acc", "gyro"))
    lines = ["t,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z"]
    for a, g in itertools.zip_longest(acc, gyro, fillvalue=""):
        fields = f"{a}\t{g}".split()
        if len(fields) != 8:
            continue
        if fields[0] != fields[4]:
            raise SystemExit(f"same: the Xsens clocks differ: {fields[0]} {fields[4]}")
        lines.append(",".join(fields[:4] + fields[5:]))
    half = len(lines) // 2
    for name, part in (("xsens", lines), ("xsens_first", lines[:half]), ("xsens_second", lines[:1] + lines[half:])):
        (folder / f"{name}.csv").write_text("".join(line + "\n" for line in part))


def environment(tree: Path, tmp: Path) -> dict[str, str]:
    """The environment of every command: ``tree``'s package first on the path (PYTHONSAFEPATH: with
    ``-m`` Python would otherwise put the working directory, this repository, before it), and all
    that decides what a command prints pinned."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONSTARTUP", "PYTHONWARNINGS", "TUMBLECAL_CONFIG")}
    env.update(
        PYTHONPATH=str(tree),
        PYTHONSAFEPATH="1",
        PYTHONDONTWRITEBYTECODE="1",
        COLUMNS="100",
        NO_COLOR="1",
        TZ="UTC",
        LC_ALL="C.UTF-8",
        LANG="C.UTF-8",
        SOURCE_DATE_EPOCH=SOURCE_DATE_EPOCH,
        TMPDIR=str(tmp),
        MPLBACKEND="Agg",
    )
    return env


def expand(argv: list[str], own: Path, scratch: Path) -> tuple[list[str], Path | None]:
    """A command's arguments with $O, $W and $IN filled in and globs expanded, and its stdin."""
    args: list[str] = []
    stdin = None
    for token in argv:
        if token.startswith("<"):
            stdin = ROOT / token[1:]
            continue
        arg = Template(token).substitute(O=str(own), W=str(scratch), IN=str(scratch / ".in"))
        matches = sorted(glob.glob(arg, root_dir=ROOT)) if "*" in arg else []
        args.extend(matches or [arg])  # as a shell would: a pattern that matches nothing stays itself
    return args, stdin


def run_all(tree: Path, scratch: Path) -> None:
    """Every command with ``tree``'s package, each into scratch/<name>: rc, stdout, stderr and
    files/ (its $O, what it wrote)."""
    shutil.rmtree(scratch, ignore_errors=True)
    (scratch / "tmp").mkdir(parents=True)
    make_inputs(scratch / ".in")
    env = environment(tree, scratch / "tmp")
    found = subprocess.run(
        [sys.executable, "-c", "import tumblecal_cli; print(tumblecal_cli.__file__)"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    if not Path(found.stdout.strip()).is_relative_to(tree):
        raise SystemExit(f"same: {tree}'s tumblecal_cli is not the one imported: {found.stdout}{found.stderr}")
    for name, argv in COMMANDS:
        own = scratch / name / "files"
        own.mkdir(parents=True)
        args, stdin = expand(argv, own, scratch)
        with open(stdin or os.devnull, "rb") as source:
            done = subprocess.run([*TUMBLECAL, *args], cwd=ROOT, env=env, stdin=source, capture_output=True)
        (scratch / name / "rc").write_text(f"{done.returncode}\n")
        (scratch / name / "stdout").write_bytes(done.stdout)
        (scratch / name / "stderr").write_bytes(done.stderr)
    shutil.rmtree(scratch / "tmp")


def take_out(rev: str, folder: Path) -> Path:
    """``rev``'s ``tumblecal_cli`` out of git into ``folder`` (as tests/bench.py's bench_against)."""
    archive = subprocess.run(["git", "archive", rev, "tumblecal_cli"], cwd=ROOT, capture_output=True)
    if archive.returncode != 0:
        raise UsageError(f"git archive {rev}: {archive.stderr.decode().strip()}")
    folder.mkdir()
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return folder


class UsageError(Exception):
    """A revision git does not know (exit 2)."""


# -- comparing -------------------------------------------------------------------------------

TOOL = re.compile(r"^tumblecal \S+$")
CAL_EXT = (".json", ".yaml", ".yml")
Norm = Callable[[str, bool], str]


def normaliser(tree: Path, tmp: Path) -> Norm:
    """Text with ``tree`` (this repository or REV's folder) as <ROOT>, temporary file names as <TMP>."""
    tmp_name = re.compile(rf"(?:{re.escape(str(tmp))}|/tmp|/var/tmp)/(?:tmp|tumblecal[-_.]?)[A-Za-z0-9_.-]{{4,}}")

    def norm(text: str, tmp_names: bool = True) -> str:
        text = text.replace(str(tree), "<ROOT>")
        return tmp_name.sub("<TMP>", text) if tmp_names else text

    return norm


def short_diff(a: str, b: str, name: str, limit: int = 16) -> str:
    lines = list(difflib.unified_diff(a.splitlines(), b.splitlines(), f"REV/{name}", f"this/{name}", lineterm="", n=1))
    if len(lines) > limit:
        lines = [*lines[:limit], f"... ({len(lines) - limit} more diff lines)"]
    return "".join("\n      " + line for line in lines)


def canon(x: object) -> object:
    """A value where equal means equal bit for bit (floats by repr: -0.0 and 0.0 apart, nan alike)."""
    if isinstance(x, float):
        return ("f", "nan" if math.isnan(x) else repr(x))
    if isinstance(x, dict):
        return ("d", tuple((k, canon(v)) for k, v in x.items()))
    if isinstance(x, list | tuple):
        return ("l", tuple(canon(v) for v in x))
    return (type(x).__name__, x)


def strip_fields(text: str, suffix: str, keys: tuple[str, ...]) -> str:
    """A calibration's text without its top-level ``keys`` lines."""
    names = "|".join(keys)
    line = re.compile(rf'^  "(?:{names})": .*$' if suffix == ".json" else rf"^(?:{names}): .*$")
    return "\n".join(x for x in text.split("\n") if not line.match(x))


def compare_cal(a: bytes, b: bytes, suffix: str) -> str | None:
    """None when not calibrations (compare the bytes); else "" when the same, or the difference."""
    try:
        ta, tb = a.decode(), b.decode()
        da, db = (json.loads(t) if suffix == ".json" else yaml.safe_load(t) for t in (ta, tb))
    except (UnicodeDecodeError, ValueError, yaml.YAMLError):
        return None
    if not all(isinstance(d, dict) and d.get("format") == "tumblecal-calibration" for d in (da, db)):
        return None
    tools = all(isinstance(d.get("tool"), str) and TOOL.match(d["tool"]) for d in (da, db))
    ignored = ("created", "tool") if tools else ("created",)
    pa = {k: v for k, v in da.items() if k not in ignored}
    pb = {k: v for k, v in db.items() if k not in ignored}
    same_values = canon(pa) == canon(pb)
    sa, sb = strip_fields(ta, suffix, ignored), strip_fields(tb, suffix, ignored)
    if sa == sb and same_values:
        return ""
    if same_values:
        return "calibration: the same values (bit for bit), other text" + short_diff(sa, sb, "")
    keys = sorted(set(pa) | set(pb), key=lambda k: (k not in pa, k))
    changed = [k for k in keys if canon(pa.get(k, "<absent>")) != canon(pb.get(k, "<absent>"))]
    return f"calibration values differ in: {', '.join(changed)}" + short_diff(sa, sb, "")


def files_of(folder: Path) -> dict[str, Path]:
    return {str(p.relative_to(folder)): p for p in sorted(folder.rglob("*")) if p.is_file() or p.is_symlink()}


def compare_file(rel: str, a: bytes, b: bytes, norm_a: Norm, norm_b: Norm) -> str | None:
    """What differs between REV's file ``rel`` and this tree's, or None."""
    suffix = Path(rel).suffix.lower()
    verdict = compare_cal(a, b, suffix) if suffix in CAL_EXT else None
    if verdict is not None:
        return f"file {rel}: {verdict}" if verdict else None
    if a == b:
        return None
    try:
        ta, tb = a.decode(), b.decode()
    except UnicodeDecodeError:
        return f"file {rel}: binary contents differ ({len(a)} vs {len(b)} bytes)"
    if norm_a(ta, False) == norm_b(tb, False):
        return None
    return f"file {rel} differs" + short_diff(ta, tb, rel)


def compare_command(ca: Path, cb: Path, norm_a: Norm, norm_b: Norm) -> list[str]:
    """What differs between one command's run with REV (``ca``) and with this tree (``cb``)."""
    diffs: list[str] = []
    rc_a, rc_b = ((c / "rc").read_text().strip() for c in (ca, cb))
    if rc_a != rc_b:
        diffs.append(f"exit code {rc_a} != {rc_b}")
    ea, eb = ((c / "stderr").read_bytes().decode(errors="replace") for c in (ca, cb))
    if norm_a(ea, True) != norm_b(eb, True):
        diffs.append("stderr differs" + short_diff(norm_a(ea, True), norm_b(eb, True), "stderr"))
    oa, ob = ((c / "stdout").read_bytes() for c in (ca, cb))
    if oa != ob:
        ta, tb = oa.decode(errors="replace"), ob.decode(errors="replace")
        if norm_a(ta, False) != norm_b(tb, False):
            diffs.append("stdout differs" + short_diff(ta, tb, "stdout"))
    fa, fb = files_of(ca / "files"), files_of(cb / "files")
    diffs += [f"file only with REV: {rel}" for rel in sorted(set(fa) - set(fb))]
    diffs += [f"file only with this tree: {rel}" for rel in sorted(set(fb) - set(fa))]
    for rel in sorted(set(fa) & set(fb)):
        diff = compare_file(rel, fa[rel].read_bytes(), fb[rel].read_bytes(), norm_a, norm_b)
        if diff is not None:
            diffs.append(diff)
    return diffs


# -- the command line ------------------------------------------------------------------------


def same(rev: str) -> int:
    """Every command with ``rev``'s package, then with this tree's, into one scratch path; a line per
    difference, then the count. 0 when every command is identical, 1 when not."""
    with tempfile.TemporaryDirectory(prefix="same-") as folder:
        base = Path(folder)
        trees = {"rev": take_out(rev, base / "against"), "this": ROOT}
        for tree in trees.values():
            compileall.compile_dir(str(tree / "tumblecal_cli"), quiet=1)
        scratch = base / "run"
        for key, tree in trees.items():
            start = time.perf_counter()
            run_all(tree, scratch)
            scratch.rename(base / key)
            what = rev if key == "rev" else "this tree"
            print(f"same: {len(COMMANDS)} commands with {what} in {time.perf_counter() - start:.0f} s", file=sys.stderr)
        norm_a, norm_b = normaliser(trees["rev"], scratch / "tmp"), normaliser(ROOT, scratch / "tmp")
        different = 0
        for name, _ in COMMANDS:
            diffs = compare_command(base / "rev" / name, base / "this" / name, norm_a, norm_b)
            different += bool(diffs)
            for diff in diffs:
                print(f"{name}: {diff}")
    print(f"{len(COMMANDS)} commands, {len(COMMANDS) - different} identical, {different} different")
    return 1 if different else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="tests/same.py",
        description="Run every command with this tree and with git revision REV, and compare their outputs.",
    )
    parser.add_argument(
        "rev", nargs="?", metavar="REV", help="the git revision to compare with (make same AGAINST=REV)"
    )
    parser.add_argument("--list", action="store_true", help="print the commands' names and exit")
    args = parser.parse_args(argv)
    if args.list:
        print("\n".join(name for name, _ in COMMANDS))
        return 0
    if args.rev is None:
        parser.error("give the revision to compare with: python tests/same.py REV (make same AGAINST=REV)")
    try:
        return same(args.rev)
    except UsageError as e:
        print(f"same: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
