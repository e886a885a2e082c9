"""``batch`` and ``apply`` with ``--dask-scheduler``: the same files as running here, on a LocalCluster.

One LocalCluster (two worker processes) serves the module. ``SOURCE_DATE_EPOCH`` is set for the
CLI only, never in the workers' environment: the workers write the calibrations, and their
``created`` time and names must follow the caller's setting. The workers' working folder is an
empty folder of their own, so a relative path cannot be found there by chance. The CLI runs as the installed
``tumblecal`` script (a subprocess: the client's connect and close stay out of pytest's process).
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import SAMPLE, run_exe, snapshot, tumblecal_exe, unit

# distributed is imported where a cluster is made: importing it here cost every run, the fast tier too
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="distributed is not installed"),
]

LIMITS = SAMPLE / "limits.yaml"
EPOCH = "1700000000"
STAMP = "20231114T221320Z"
UNREACHABLE = "tcp://127.0.0.1:1"


#: added to the CLI's environment, never to the workers': their clock is theirs, the caller's setting wins
CLI_ENV = {"SOURCE_DATE_EPOCH": EPOCH}


def make_units(root: Path) -> Path:
    """Six units: pass (two), fail (limits), rejected, error; more units than workers."""
    for serial, kind in [("A", "good"), ("B", "six"), ("C", "rejected"), ("D", "error"), ("E", "good"), ("F", "six")]:
        unit(root, serial, kind)
    return root


def make_captures(folder: Path) -> list[Path]:
    folder.mkdir(parents=True)
    lines = (SAMPLE / "capture.csv").read_text().splitlines(keepends=True)
    texts = {"c1.csv": lines, "c2.csv": lines[:101], "c3.csv": [lines[0], *lines[-50:]], "c4.csv": lines[:2000]}
    for name, text in texts.items():
        (folder / name).write_text("".join(text))
    return [folder / name for name in texts]


# -- the cluster ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    import distributed

    home = tmp_path_factory.mktemp("dask_workers")
    with pytest.MonkeyPatch.context() as env:
        env.delenv("SOURCE_DATE_EPOCH", raising=False)  # the workers' clock is theirs; the caller's setting wins
        with pytest.MonkeyPatch.context() as cwd:
            cwd.chdir(home)  # the workers' working folder
            cluster = distributed.LocalCluster(
                n_workers=2,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # a free port: None still takes 8787 (distributed 2026.8)
                local_directory=str(home / "scratch"),
            )
        try:
            yield str(cluster.scheduler_address)
        finally:
            cluster.close()


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    r = run_exe(
        ["solve", "-q", "--poses", *(SAMPLE / f"{n}.csv" for n in "xyz"), "-o", path],
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    return path


# -- batch ---------------------------------------------------------------------------------------


def test_batch_on_dask_is_byte_identical_to_local(tmp_path: Path, scheduler: str) -> None:
    src = make_units(tmp_path / "units")
    local = run_exe(
        ["batch", src, "--out-dir", tmp_path / "local", "--max-offset", "0.05"], text=True, env=CLI_ENV, timeout=120
    )
    dask = run_exe(
        ["batch", src, "--out-dir", tmp_path / "dask", "--max-offset", "0.05", "--dask-scheduler", scheduler],
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    assert local.returncode == 2, local.stderr
    assert dask.returncode == 2, dask.stderr
    assert dask.stdout == ""
    assert "Traceback" not in dask.stderr
    first, second = snapshot(tmp_path / "local"), snapshot(tmp_path / "dask")
    assert sorted(first) == sorted([*(f"{s}_{STAMP}.json" for s in "ABEF"), "summary.csv"])
    assert second == first
    # the same lines per unit (in the order they finished), and the same totals
    assert sorted(dask.stderr.replace(str(tmp_path / "dask"), "OUT").splitlines()) == sorted(
        local.stderr.replace(str(tmp_path / "local"), "OUT").splitlines()
    )


def test_batch_on_dask_records_the_pose_files_as_local(tmp_path: Path, scheduler: str) -> None:
    """UNITS given relative to the working folder: the workers read absolute paths, but each
    calibration's poses[*].file (and summary.csv's inputs and messages) name the files as a
    local batch does, relative as given."""
    make_units(tmp_path / "units")
    local = run_exe(
        ["batch", "units", "--out-dir", "local", "--max-offset", "0.05"],
        cwd=tmp_path,
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    dask = run_exe(
        ["batch", "units", "--out-dir", "dask", "--max-offset", "0.05", "--dask-scheduler", scheduler],
        cwd=tmp_path,
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    assert (local.returncode, dask.returncode) == (2, 2), dask.stderr
    for serial in "ABEF":
        here, there = (json.loads((tmp_path / d / f"{serial}_{STAMP}.json").read_text()) for d in ("local", "dask"))
        files = [p["file"] for p in here["poses"]]
        assert all(f.startswith(os.path.join("units", serial, "")) for f in files), files
        assert [p["file"] for p in there["poses"]] == files
    assert snapshot(tmp_path / "dask") == snapshot(tmp_path / "local")  # rows, inputs and messages too
    assert str(tmp_path) not in (tmp_path / "dask" / "summary.csv").read_text()


def test_batch_on_dask_json_and_resume(tmp_path: Path, scheduler: str) -> None:
    src = make_units(tmp_path / "units")
    local = run_exe(
        ["batch", src, "--out-dir", tmp_path / "local", "--json", "-q"], text=True, env=CLI_ENV, timeout=120
    )
    assert local.returncode == 2, local.stderr
    # a batch that stopped after units A and C, resumed on the cluster
    out = tmp_path / "dask"
    out.mkdir()
    header, *rows = (tmp_path / "local" / "summary.csv").read_text().splitlines(keepends=True)
    kept = [r for r in rows if r.startswith(("A,", "C,"))]
    (out / "summary.csv").write_text(header + "".join(kept))
    shutil.copy(tmp_path / "local" / f"A_{STAMP}.json", out)
    dask = run_exe(
        ["batch", src, "--out-dir", out, "--json", "-q", "--resume", "--dask-scheduler", scheduler],
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    assert dask.returncode == 2
    assert [line.split(":")[0] for line in dask.stderr.splitlines()] == ["D"]  # -q: the unit with an error
    assert dask.stdout == local.stdout.replace(str(tmp_path / "local"), str(out))
    assert snapshot(out) == snapshot(tmp_path / "local")


@pytest.mark.parametrize("what", ["batch", "apply"])
def test_dask_relative_paths_are_the_clients(what: str, tmp_path: Path, scheduler: str, calibration: Path) -> None:
    """Relative paths are this process's: the client makes them absolute before sending them to
    workers that run in another folder. A batch's calibrations still name their pose files as
    given, relative, as a local run does (apply's outputs hold no input path: compared with a
    local run given absolute paths)."""
    if what == "batch":
        make_units(tmp_path / "units")
        args: list[str | Path] = ["batch", "units", "--limits", LIMITS]
        absolute: list[str | Path] = args
    else:
        make_captures(tmp_path / "caps")
        shutil.copy(calibration, tmp_path / "cal.json")
        args = ["apply", "--cal", "cal.json", "caps/*.csv"]
        absolute = ["apply", "--cal", tmp_path / "cal.json", f"{tmp_path}/caps/*.csv"]
    local = run_exe([*absolute, "--out-dir", "local"], cwd=tmp_path, text=True, env=CLI_ENV, timeout=120)
    dask = run_exe(
        [*args, "--out-dir", "dask", "--dask-scheduler", scheduler], cwd=tmp_path, text=True, env=CLI_ENV, timeout=120
    )
    assert dask.returncode == local.returncode, dask.stderr
    assert snapshot(tmp_path / "dask") == snapshot(tmp_path / "local")


# -- apply ---------------------------------------------------------------------------------------


def test_apply_glob_on_dask_is_byte_identical_to_local(tmp_path: Path, scheduler: str, calibration: Path) -> None:
    paths = make_captures(tmp_path / "caps")
    pattern = str(tmp_path / "caps" / "*.csv")
    local = run_exe(
        ["apply", "--cal", calibration, pattern, "--out-dir", tmp_path / "local"], text=True, env=CLI_ENV, timeout=120
    )
    dask = run_exe(
        ["apply", "--cal", calibration, pattern, "--out-dir", tmp_path / "dask", "--dask-scheduler", scheduler],
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    assert local.returncode == 0, local.stderr
    assert dask.returncode == 0, dask.stderr
    assert dask.stdout == ""
    first, second = snapshot(tmp_path / "local"), snapshot(tmp_path / "dask")
    assert sorted(first) == [p.name for p in paths]
    assert second == first
    for p in paths:
        assert f"corrected {p} -> {tmp_path / 'dask' / p.name}" in dask.stderr


def test_apply_on_dask_one_bad_capture(tmp_path: Path, scheduler: str, calibration: Path) -> None:
    paths = make_captures(tmp_path / "caps")
    bad = tmp_path / "caps" / "c0.csv"
    bad.write_text("foo,bar\n1,2\n")
    pattern = str(tmp_path / "caps" / "*.csv")
    dask = run_exe(
        ["apply", "--cal", calibration, pattern, "--out-dir", tmp_path / "dask", "--dask-scheduler", scheduler],
        text=True,
        env=CLI_ENV,
        timeout=120,
    )
    assert dask.returncode == 2
    errors = [line for line in dask.stderr.splitlines() if line.startswith("error:")]
    assert errors[0].startswith(f"error: {bad}: ")
    assert errors[-1] == f"error: 1 of 5 captures failed (above); the others are in {tmp_path / 'dask'}"
    assert sorted(os.listdir(tmp_path / "dask")) == [p.name for p in paths]


# -- an unreachable scheduler --------------------------------------------------------------------


@pytest.fixture(scope="module")
def unreachable(tmp_path_factory: pytest.TempPathFactory, calibration: Path) -> dict[str, tuple[int, str, float, Path]]:
    """batch and apply against a scheduler nobody listens on, at the same time (each waits out its
    connect timeout): the exit status, stderr, seconds taken and the out dir of each."""
    root = tmp_path_factory.mktemp("unreachable")
    src = make_units(root / "units")
    make_captures(root / "caps")
    jobs: dict[str, list[str | Path]] = {
        "batch": ["batch", src, "--out-dir", root / "batch_out"],
        "apply": ["apply", "--cal", calibration, root / "caps" / "*.csv", "--out-dir", root / "apply_out"],
    }
    for args in jobs.values():
        args += ["--dask-scheduler", UNREACHABLE]
    start = time.monotonic()
    procs = {
        name: subprocess.Popen(
            [tumblecal_exe(), *map(str, args)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "NO_COLOR": "1", **CLI_ENV},
        )
        for name, args in jobs.items()
    }
    results: dict[str, tuple[int, str, float, Path]] = {}
    for name, proc in procs.items():
        out, err = proc.communicate(timeout=120)
        assert out == ""
        results[name] = (proc.returncode, err, time.monotonic() - start, root / f"{name}_out")
    return results


@pytest.mark.parametrize("what", ["batch", "apply"])
def test_unreachable_scheduler_is_exit_2(what: str, unreachable: dict[str, tuple[int, str, float, Path]]) -> None:
    code, err, seconds, _ = unreachable[what]
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert lines[0].startswith(f"error: cannot reach the Dask scheduler at {UNREACHABLE}: ")
    assert lines[1].startswith("hint: ")
    assert "dask scheduler" in lines[1]
    assert len(lines) == 2
    assert seconds < 30, f"{seconds:.1f} s to give up on the scheduler"


def test_unreachable_scheduler_leaves_no_summary(unreachable: dict[str, tuple[int, str, float, Path]]) -> None:
    assert not (unreachable["batch"][3] / "summary.csv").exists()


def test_a_scheduler_without_workers_is_exit_2_not_a_hang(tmp_path: Path) -> None:
    """The scheduler would accept the units and never run them: after 10 s with no worker,
    a clear error, and nothing written."""
    import distributed

    cluster = distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=":0")
    try:
        src = make_units(tmp_path / "units")
        started = time.monotonic()
        r = run_exe(
            ["batch", src, "--out-dir", tmp_path / "out", "--dask-scheduler", cluster.scheduler_address],
            text=True,
            env=CLI_ENV,
            timeout=120,
        )
        assert r.returncode == 2, r.stderr
        assert r.stderr.splitlines()[0].startswith(
            f"error: the Dask scheduler at {cluster.scheduler_address} has no workers"
        )
        assert time.monotonic() - started < 60
        assert not (tmp_path / "out").exists()
    finally:
        cluster.close()
