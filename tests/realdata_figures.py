"""The real-data figures of ``tests/test_solvers_realdata.py`` as a markdown table (for docs/accuracy.md).

    .venv/bin/python tests/realdata_figures.py [--detail]

Not a test (pytest does not collect it). Each row is one solver on one public recording, judged
by ``tumblecal verify``: the norm error ``|corrected mean| - reference`` of static captures the
calibration was not fitted on (RMS and largest over those captures), and the same for the raw
means where the raw data is already in the output units ("before"). Rows marked "(self-check)"
are verified on the poses they were fitted on: any method fitted on six poses reads the
reference there nearly by construction, so they compare methods, not calibrations. ``--detail``
also lists the error of every capture.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _g(value: float | None) -> str:
    return "—" if value is None else f"{value:.2g}" if abs(value) < 0.001 else f"{value:.4f}"


def main(argv: list[str]) -> int:
    sys.path.insert(0, str(ROOT))  # run as a script: make the tests package importable
    from tests.test_solvers_realdata import all_figures

    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        rows = all_figures(Path(tmp))
    elapsed = time.perf_counter() - started
    print("| dataset | method | fitted on | verified on | units | RMS after | max after | RMS before | max before |")
    print("|---|---|---|---|---|---:|---:|---:|---:|")
    for h in rows:
        verified = h.verified_on if h.held_out else f"{h.verified_on} (self-check)"
        print(
            f"| {h.dataset} | {h.method} | {h.fitted_on} | {verified} | {h.units} | {_g(h.rms_after)} | "
            f"{_g(h.max_after)} | {_g(h.rms_before)} | {_g(h.max_before)} |"
        )
    if "--detail" in argv:
        for h in rows:
            print(f"\n{h.dataset}, {h.method}, fitted on {h.fitted_on}, verified on {h.verified_on}:")
            for i, name in enumerate(h.captures):
                before = "" if h.before is None else f"  before {h.before[i]:+.5f}"
                print(f"  {name:28s} after {h.after[i]:+.5f}{before}")
    print(f"\n({len(rows)} rows in {elapsed:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
