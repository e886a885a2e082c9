"""Hostile input, round two: outputs that race, and exports that our own ``import`` or a C
compiler would reject. Each test is named for the defect it pins, and failed before its fix."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from tests.conftest import POSES_3, SAMPLE, run, tumblecal_exe
from tumblecal_cli.pipeline import correct as correct_module

OTHER_RUN = b"t,ax,ay,az\n0,1,2,3\n"


@pytest.fixture
def cal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    path = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", path).code == 0
    return path


# -- apply --out-dir: the check that a name is free and the publish are one step ------------------


def test_apply_out_dir_never_replaces_a_file_another_run_writes_meanwhile(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two runs correcting captures of one name into one folder: the other run's file appears
    after this run's "never replaces a file" check, while it streams. Before: both exited 0 and
    the other run's output was silently replaced. Now: this run is exit 2 naming the file, the
    other run's output stays as it was, and no temporary file is left behind."""
    out = tmp_path / "out"
    capture = tmp_path / "a" / "capture.csv"
    capture.parent.mkdir()
    capture.write_bytes((SAMPLE / "capture.csv").read_bytes())
    stream = correct_module._stream

    def other_run_first(*args: object) -> int:  # the other run publishes while this one streams
        (out / "capture.csv").write_bytes(OTHER_RUN)
        return stream(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(correct_module, "_stream", other_run_first)
    r = run(capsys, "apply", "--cal", cal, capture, "--out-dir", out)
    assert r.code == 2, r.err
    assert r.out == ""
    assert "Traceback" not in r.err
    errors = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert any(f"{out / 'capture.csv'}: already exists" in ln for ln in errors), r.err
    assert (out / "capture.csv").read_bytes() == OTHER_RUN
    assert sorted(os.listdir(out)) == ["capture.csv"], "no temporary file is left behind"


@pytest.mark.slow
def test_apply_out_dir_two_runs_racing_for_one_name_never_both_succeed(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The race as it happens: two processes correct different captures named alike into one
    folder, three times. Each time exactly one exits 0 and its output is the file there; the
    other exits 2 naming the file (before: both exited 0, one output lost, 4 tries in 6)."""
    lines = (SAMPLE / "capture.csv").read_bytes().splitlines(keepends=True)
    captures = []
    for name, rows in (("a", lines), ("b", lines[: len(lines) // 2])):
        (tmp_path / name).mkdir()
        captures.append(tmp_path / name / "capture.csv")
        captures[-1].write_bytes(b"".join(rows))
    wanted = []
    for k, capture in enumerate(captures):
        alone = tmp_path / f"alone{k}"
        assert run(capsys, "apply", "--cal", cal, capture, "--out-dir", alone).code == 0
        wanted.append((alone / "capture.csv").read_bytes())
    for attempt in range(3):
        out = tmp_path / f"out{attempt}"
        runs = [
            subprocess.Popen(
                [tumblecal_exe(), "apply", "--cal", str(cal), str(c), "--out-dir", str(out)],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                env={**os.environ, "NO_COLOR": "1"},
            )
            for c in captures
        ]
        done = [(p.wait(timeout=120), p.stderr.read().decode() if p.stderr else "") for p in runs]
        for p in runs:
            for stream in (p.stdout, p.stderr):
                if stream:
                    stream.close()
        codes = [code for code, _ in done]
        assert sorted(codes) == [0, 2], done
        winner, loser = codes.index(0), codes.index(2)
        assert (out / "capture.csv").read_bytes() == wanted[winner]
        assert f"{out / 'capture.csv'}: already exists" in done[loser][1]
        assert "Traceback" not in done[loser][1]
        assert sorted(os.listdir(out)) == ["capture.csv"], "no temporary file is left behind"
