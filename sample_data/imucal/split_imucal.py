"""Split imucal's annotated Ferraris session into one CSV per static pose.

Each output is the source's header line followed by exactly the source lines whose
``part`` column has that label, byte for byte and in the original order (numbers are
not re-formatted; every column, including ``part``, is kept). The rotation parts
(x_rot, y_rot, z_rot) are not written.

Usage: python split_imucal.py [SOURCE_CSV]

SOURCE_CSV defaults to (relative to this script)
../../../shared/realdata/imucal_annotated/raw/annotated_session.csv.
Outputs are written next to this script.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
DEFAULT_SOURCE = HERE / "../../../shared/realdata/imucal_annotated/raw/annotated_session.csv"

# imucal label -> output file (x_p: x reads +1 g, x_a: x reads -1 g, ...)
PARTS = {
    "x_p": "xp.csv",
    "x_a": "xn.csv",
    "y_p": "yp.csv",
    "y_a": "yn.csv",
    "z_p": "zp.csv",
    "z_a": "zn.csv",
}


def main(argv: list[str]) -> int:
    """Write one CSV per static part; return the exit status."""
    source = Path(argv[1]) if len(argv) > 1 else DEFAULT_SOURCE
    lines = source.read_bytes().splitlines(keepends=True)
    header, rows = lines[0], lines[1:]
    if not header.startswith(b"part,"):
        sys.exit(f"{source}: expected a 'part' first column, got {header!r}")

    chunks: dict[str, list[bytes]] = {label: [header] for label in PARTS}
    for row in rows:
        label = row.split(b",", 1)[0].decode("ascii")
        if label in chunks:
            chunks[label].append(row)

    for label, name in PARTS.items():
        if len(chunks[label]) == 1:
            sys.exit(f"{source}: no rows labelled {label!r}")
        (HERE / name).write_bytes(b"".join(chunks[label]))
        print(f"{name}: {len(chunks[label]) - 1} rows ({label})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
