"""A calibration in other tools' terms: firmware (C header, offset registers), imucal, ROS
imu_calib and MATLAB (``tumblecal export``), and imucal/ROS files read back (``tumblecal import``).

Every mapping starts from tumblecal's model (docs/reference/model.md): ``corrected = M (raw - b)``,
``A = M^-1``. Each peer's own equation is quoted where it is used; docs/commands/export-import.md writes them out.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np

from tumblecal_cli.core import catalog
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import SENSORS
from tumblecal_cli.core.quantities import STANDARD_GRAVITY
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles.calfile import (
    FORMAT,
    VERSION,
    Calibration,
    Unit,
    created,
    from_dict,
    invertible,
    is_number,
)
from tumblecal_cli.io.calfiles.documents import parse_object
from tumblecal_cli.io.calfiles.limitfile import triplet
from tumblecal_cli.io.export.contract import Exported, Exporter, ExportOptions, Importer, Peer, Record
from tumblecal_cli.version import __version__

#: imucal's calibration file format (imucal/calibration_info.py, _CAL_FORMAT_VERSION); its
#: loader also reads files without the key as the legacy 1.0 layout, which has the same fields.
IMUCAL_FORMAT_VERSION = "2.0.0"
IMUCAL_VERSIONS = (None, "1.0.0", IMUCAL_FORMAT_VERSION)
FLOAT32_MAX = 3.4028234663852886e38
SHORT = {"accelerometer": "accel", "magnetometer": "mag", "gyroscope": "gyro"}


def a_matrix(cal: Calibration) -> FloatArray:
    """A = M^-1: raw = A v + b (docs/reference/model.md)."""
    return np.asarray(np.linalg.inv(cal.matrix), dtype=np.float64)


def scale_and_rotation(matrix: FloatArray) -> tuple[FloatArray, FloatArray]:
    """imucal's K (diagonal scale) and R (rows of unit length) with K R = A = M^-1.

    imucal (FerrarisCalibrationInfo.calibrate_acc) computes ``R^-1 K^-1 (raw - b)``, so
    ``M = R^-1 K^-1`` and ``K R = M^-1``: K_ii is the length of row i of A (Ferraris et al. 1995
    eq. 2, where each row of R is the unit sensitive direction of one axis).
    """
    a = np.linalg.inv(matrix)
    k = np.linalg.norm(a, axis=1)
    return np.diag(k), a / k[:, None]


# -- firmware ---------------------------------------------------------------------------


def c_header(cal: Calibration, *, prefix: str | None = None) -> str:
    """A self-contained C99/C++ header: offset and M as ``static const float``, and an inline
    function that applies them, with the model and the unit's record in a comment."""
    name = (prefix or f"tumblecal_{SHORT[cal.sensor]}").lower()
    if not re.fullmatch(r"[a-z_][a-z0-9_]*", name):
        raise InputError(f"--prefix {prefix!r} is not a C identifier (letters, digits and '_')")
    upper = name.upper()
    offset = ", ".join(_c_float(v, f"offset[{i}]", cal.path) for i, v in enumerate(cal.offset))
    rows = ",\n    ".join(
        "{" + ", ".join(_c_float(v, f"matrix[{i}][{j}]", cal.path) for j, v in enumerate(row)) + "}"
        for i, row in enumerate(cal.matrix)
    )
    lines = [
        f"/* {_c_comment(cal.sensor)} calibration, written by tumblecal {__version__} from {_c_comment(str(cal.path))}",
        " *",
        *[f" * {_c_comment(line)}" for line in provenance(cal)],
        " *",
        " * Model: corrected = M * (raw - offset), axes in the order x, y, z:",
        " *   corrected[i] = M[i][0]*(raw[0] - offset[0]) + M[i][1]*(raw[1] - offset[1])",
        " *                + M[i][2]*(raw[2] - offset[2])",
        f" * {upper}_OFFSET is offset (raw units), {upper}_MATRIX is M (row i gives corrected[i]).",
        " * Values are rounded to float (24-bit mantissa): about 6e-8 relative.",
        " */",
        f"#ifndef {upper}_H",
        f"#define {upper}_H",
        "",
        "#ifndef TUMBLECAL_UNUSED",
        "#if defined(__GNUC__) || defined(__clang__)",
        "#define TUMBLECAL_UNUSED __attribute__((unused))",
        "#else",
        "#define TUMBLECAL_UNUSED",
        "#endif",
        "#endif",
        "",
        f"static const float {upper}_OFFSET[3] TUMBLECAL_UNUSED = {{{offset}}};",
        "",
        f"static const float {upper}_MATRIX[3][3] TUMBLECAL_UNUSED = {{",
        f"    {rows}",
        "};",
        "",
        f"/* out = {upper}_MATRIX * (raw - {upper}_OFFSET); out may be raw itself. */",
        f"static inline void {name}_apply(const float raw[3], float out[3])",
        "{",
        f"    const float d0 = raw[0] - {upper}_OFFSET[0];",
        f"    const float d1 = raw[1] - {upper}_OFFSET[1];",
        f"    const float d2 = raw[2] - {upper}_OFFSET[2];",
        "    int i;",
        "    for (i = 0; i < 3; i++) {",
        f"        out[i] = {upper}_MATRIX[i][0] * d0 + {upper}_MATRIX[i][1] * d1 + {upper}_MATRIX[i][2] * d2;",
        "    }",
        "}",
        "",
        *_c_thermal(cal, name, upper),
        f"#endif /* {upper}_H */",
    ]
    return "\n".join(lines) + "\n"


def _c_thermal(cal: Calibration, name: str, upper: str) -> list[str]:
    """A thermal block in a C header: its coefficients and ``name_apply_at(raw, temp_c, out)``,
    core.drift.correct in C (the drift polynomials in d = clamp(T) - T_ref, Horner's rule)."""
    if cal.thermal is None:
        return []
    t = cal.thermal
    k = t.order

    def table(values: FloatArray, what: str) -> str:
        return ",\n    ".join(
            "{" + ", ".join(_c_float(float(v), f"thermal.{what}", cal.path) for v in row) + "}" for row in values
        )

    limits = (("T_REF", t.reference_temperature), ("T_MIN", t.range[0]), ("T_MAX", t.range[1]))
    return [
        f"/* Temperature drift (docs/commands/thermal.md), order {k}, in d = clamp(T) - T_REF, degC:",
        " *   offset_drift[i] = sum_k OFFSET_DRIFT[i][k-1] d^k  (raw units)",
        " *   gain_drift[i]   = sum_k GAIN_DRIFT[i][k-1] d^k    (relative)",
        " *   corrected = M * ((raw - offset - offset_drift) / (1 + gain_drift)) */",
        *(f"static const float {upper}_{w} TUMBLECAL_UNUSED = {_c_float(v, 'thermal', cal.path)};" for w, v in limits),
        f"static const float {upper}_OFFSET_DRIFT[3][{k}] TUMBLECAL_UNUSED = {{",
        f"    {table(t.offset, 'offset')}",
        "};",
        f"static const float {upper}_GAIN_DRIFT[3][{k}] TUMBLECAL_UNUSED = {{",
        f"    {table(t.gain, 'gain')}",
        "};",
        "",
        f"/* sum_k c[k-1] d^k, k = 1..{k} (Horner's rule) */",
        f"static inline float {name}_drift(const float c[{k}], float d)",
        "{",
        "    float p = 0.0f;",
        "    int k;",
        f"    for (k = {k - 1}; k >= 0; k--) {{",
        "        p = (p + c[k]) * d;",
        "    }",
        "    return p;",
        "}",
        "",
        "/* out = M ((raw - offset - offset_drift) / (1 + gain_drift)) at temp_c (clamped); out may be raw. */",
        f"static inline void {name}_apply_at(const float raw[3], float temp_c, float out[3])",
        "{",
        f"    const float t = temp_c < {upper}_T_MIN ? {upper}_T_MIN : temp_c;",
        f"    const float d = (t > {upper}_T_MAX ? {upper}_T_MAX : t) - {upper}_T_REF;",
        "    float v[3];",
        "    int i;",
        "    for (i = 0; i < 3; i++) {",
        f"        v[i] = (raw[i] - {upper}_OFFSET[i] - {name}_drift({upper}_OFFSET_DRIFT[i], d))",
        f"             / (1.0f + {name}_drift({upper}_GAIN_DRIFT[i], d));",
        "    }",
        "    for (i = 0; i < 3; i++) {",
        f"        out[i] = {upper}_MATRIX[i][0] * v[0] + {upper}_MATRIX[i][1] * v[1] + {upper}_MATRIX[i][2] * v[2];",
        "    }",
        "}",
        "",
    ]


@dataclass(frozen=True)
class Register:
    """One register value: ``count`` to write, what it does, and what was wanted."""

    name: str
    count: int
    hex: str
    value: float  # what the part does with ``count``: the offset it removes, or its gain factor
    target: float  # what the calibration asks for
    error: float  # target - value: what rounding to whole counts leaves


def registers(
    cal: Calibration,
    *,
    lsb: float,
    bits: int,
    sign: str = "subtract",
    gain_step: float | None = None,
    nominal_gain: FloatArray | None = None,
) -> list[Register]:
    """Offsets (and gain trims with ``gain_step``) in register counts, checked against the
    signed ``bits``-wide range (Okasho n.d. writes hard-iron offsets into int16 registers).

    ``sign`` says what the part does with an offset register: ``subtract`` (output = raw -
    count * lsb, so count = round(b / lsb)) or ``add`` (output = raw + count * lsb). A gain trim
    multiplies the axis by ``1 + count * gain_step``; the wanted factor takes the axis's gain to
    ``nominal_gain`` (raw units per output unit), so count = round((nominal / gain - 1) / step).
    """
    low, high = -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
    factor = 1.0 if sign == "subtract" else -1.0
    out = []
    misfits: list[InputError] = []  # every register that does not fit is named, not just the first
    for axis, b in zip("xyz", cal.offset, strict=True):
        why = f"offset {b:.6g} / --lsb {lsb:g}" if sign == "subtract" else f"-(offset {b:.6g}) / --lsb {lsb:g}"
        try:
            count = _fit(f"offset_{axis}", b / lsb * factor, low, high, bits, why, cal, OFFSET_HINT)
        except InputError as err:
            misfits.append(err)
            continue
        removed = factor * count * lsb + 0.0  # + 0.0: no "-0" for a zero count
        out.append(Register(f"offset_{axis}", count, _hex(count, bits), removed, float(b), float(b - removed)))
    if gain_step is not None:
        nominal = np.ones(3) if nominal_gain is None else nominal_gain
        gain = np.diag(np.linalg.inv(cal.sensor_matrix))  # the sensor's own axes, as its registers
        for axis, g, n in zip("xyz", gain, nominal, strict=True):
            want = float(n / g)
            if not 0.5 <= want <= 2:  # a trim corrects a few percent: anything else is a units mistake
                raise InputError(
                    f"gain_{axis}: the trim would scale the axis by {want:.4g} (nominal {n:.6g} / gain {g:.6g})",
                    file=cal.path,
                    hint="--nominal-gain is in the calibration's raw units per output unit, like its gain",
                )
            try:
                count = _fit(
                    f"gain_{axis}", (want - 1) / gain_step, low, high, bits, f"factor {want:.6g}", cal, GAIN_HINT
                )
            except InputError as err:
                misfits.append(err)
                continue
            value = 1 + count * gain_step
            out.append(Register(f"gain_{axis}", count, _hex(count, bits), value, want, want - value))
    if misfits:
        first = misfits[0]
        raise InputError(first.message, file=first.file, hint=first.hint, more=tuple(str(e) for e in misfits[1:]))
    return out


OFFSET_HINT = "check --lsb (raw units per register count) against the calibration's raw units, or --bits"
GAIN_HINT = "check --gain-step (what one count adds to the factor) and --nominal-gain, or --bits"


def export_registers(cal: Calibration, options: ExportOptions) -> Exported:
    """export --format registers: offset (and gain trim) register counts, CSV."""
    lsb, gain_step, nominal_gain = options.lsb, options.gain_step, options.nominal_gain
    if not (lsb is not None and math.isfinite(lsb) and lsb > 0):
        raise InputError(f"--lsb must be a positive number, got {lsb}")
    if gain_step is not None and not (math.isfinite(gain_step) and gain_step > 0):
        raise InputError(f"--gain-step must be a positive number, got {gain_step}")

    if gain_step is not None and catalog.fixes_gains(cal.method):
        raise InputError(f"the {cal.method} solver fixes the gains: there is no gain to trim", file=cal.path)
    verdict = cal.verdict
    recorded = verdict.limits.nominal_gain if verdict and "nominal_gain" in verdict.limit_names else None
    nominal = triplet(nominal_gain or ",".join(map(str, [1, 1, 1] if recorded is None else recorded)), "--nominal-gain")
    if not (nominal > 0).all():
        raise InputError(f"--nominal-gain must be positive, got {nominal_gain}")
    rows = registers(
        cal, lsb=lsb, bits=options.bits, sign=options.register_sign, gain_step=gain_step, nominal_gain=nominal
    )
    return Exported(registers_csv(rows))


def registers_csv(rows: list[Register]) -> str:
    lines = ["register,count,hex,value,target,error"]
    lines += [f"{r.name},{r.count},{r.hex},{r.value:.12g},{r.target!r},{r.error:.12g}" for r in rows]
    return "\n".join(lines) + "\n"


def _fit(name: str, exact: float, low: int, high: int, bits: int, why: str, cal: Calibration, hint: str) -> int:
    count = round(exact) if math.isfinite(exact) else None
    if count is None or not low <= count <= high:
        shown = "an infinite number of" if count is None else f"{count:.6g}" if abs(count) > 1e12 else f"{count}"
        raise InputError(
            f"{name} needs {shown} register counts ({why}), outside the signed {bits}-bit range {low}..{high}",
            file=cal.path,
            hint=hint,
        )
    return int(count)


def _hex(count: int, bits: int) -> str:
    """Two's complement in ``bits`` bits, as a register map shows it."""
    return f"0x{count & ((1 << bits) - 1):0{(bits + 3) // 4}X}"


# -- peer tools ---------------------------------------------------------------------------


def imucal_json(cal: Calibration) -> str:
    """imucal's FerrarisCalibrationInfo as its ``to_json`` writes it (format 2.0.0).

    imucal corrects ``acc = R_a^-1 K_a^-1 (raw - b_a)`` and ``gyr = R_g^-1 K_g^-1 (raw - K_ga acc
    - b_g)``: the calibrated sensor goes in its slot, the other slot is the identity (K = R = I,
    b = K_ga = 0), so imucal passes that sensor's data through unchanged.
    """
    if cal.sensor == "magnetometer":
        raise InputError(
            "imucal's format holds accelerometer and gyroscope calibrations only, not a magnetometer",
            file=cal.path,
            hint="use --format ros-yaml, matlab or c-header",
        )
    k, r = scale_and_rotation(cal.matrix)
    eye, zero = np.eye(3), np.zeros(3)
    ours = {"K": k, "R": r, "b": cal.offset}
    none: dict[str, FloatArray] = {"K": eye, "R": eye, "b": zero}
    acc, gyr = (ours, none) if cal.sensor == "accelerometer" else (none, ours)
    units, raw_units = cal.units or "a.u.", cal.input_units or "a.u."
    doc = {
        "acc_unit": units if acc is ours else "a.u.",
        "gyr_unit": units if gyr is ours else "a.u.",
        "from_acc_unit": raw_units if acc is ours else "a.u.",
        "from_gyr_unit": raw_units if gyr is ours else "a.u.",
        "comment": json.dumps({"about": "; ".join(provenance(cal)), "tumblecal": record(cal)}),
        "K_a": acc["K"].tolist(),
        "R_a": acc["R"].tolist(),
        "b_a": acc["b"].tolist(),
        "K_g": gyr["K"].tolist(),
        "R_g": gyr["R"].tolist(),
        "K_ga": np.zeros((3, 3)).tolist(),
        "b_g": gyr["b"].tolist(),
        "cal_type": "Ferraris",
        "_format_version": IMUCAL_FORMAT_VERSION,
    }
    return json.dumps(doc, indent=4) + "\n"


def ros_yaml(cal: Calibration) -> str:
    """ROS imu_calib's calibration file: ``SM`` (9 values, row-major) and ``bias`` (3).

    imu_calib (src/accel_calib/accel_calib.cpp, applyCalib) computes ``SM raw - bias``; equal to
    ``M (raw - b)`` when SM = M and bias = M b.
    """
    bias = cal.matrix @ cal.offset
    lines = [
        "# ROS imu_calib calibration (apply_calib computes SM * raw - bias), written by tumblecal",
        *[f"# {line}" for line in provenance(cal)],
        f"SM: [{', '.join(repr(float(v)) for v in cal.matrix.ravel())}]",
        f"bias: [{', '.join(repr(float(v)) for v in bias)}]",
        f"tumblecal: {_yaml_flow(record(cal))}",  # JSON is YAML: what import brings back (imu_calib ignores it)
    ]
    return "\n".join(lines) + "\n"


def matlab(cal: Calibration) -> str:
    """A MATLAB/Octave script defining ``A`` and ``b`` in ``accelcal``'s convention.

    MATLAB's accelcal corrects row vectors, ``C = U*A + b``: with ``c = M (u - offset)`` for a
    column u, ``c' = u' M' - (M offset)'``, so A = M' and b = -(M offset)'.
    """
    a, b = cal.matrix.T, -(cal.matrix @ cal.offset)
    lines = [
        "% tumblecal calibration for MATLAB/Octave, in accelcal's convention:",
        "%   C = U*A + b   (U: N-by-3 raw readings, one sample per row; C: corrected)",
        *[f"% {line}" for line in provenance(cal)],
        "A = [" + ";\n     ".join(" ".join(f"{float(v)!r}" for v in row) for row in a) + "];",
        "b = [" + " ".join(f"{float(v)!r}" for v in b) + "];",
    ]
    return "\n".join(lines) + "\n"


# -- import -------------------------------------------------------------------------------


#: The fields of the record an export carries in a data field (docs/commands/export-import.md), and their types.
RECORD_FIELDS: dict[str, tuple[type, ...]] = {
    "sensor": (str,),
    "serial": (str,),
    "station": (str,),
    "operator": (str,),
    "created": (str,),
    "method": (str,),
    "input_units": (str,),
    "units": (str,),
    "reference": (int, float),
    "columns": (list,),
}


def record(cal: Calibration) -> dict[str, object]:
    """What an export records of the calibration for `import` to bring back: a data field of the
    peer's file (never comment text that import would have to parse)."""
    unit = (cal.unit or Unit()).as_dict()
    return {
        "sensor": cal.sensor,
        **{k: unit.get(k) for k in ("serial", "station", "operator")},
        "created": cal.created,
        "method": cal.method,
        "input_units": cal.input_units,
        "units": cal.units,
        "reference": float(cal.reference),
        "columns": list(cal.columns),
    }


def recorded(value: object, path: str, where: str) -> Record:
    """The record of a tumblecal export read back from its data field ``where`` (None or absent:
    another tool's file, nothing recorded); each field validated, naming it."""
    if value is None:
        return Record()
    if not isinstance(value, dict):
        raise InputError(f"field {where!r} must be an object (what a tumblecal export recorded)", file=path)
    out: dict[str, object] = {}
    for key, kinds in RECORD_FIELDS.items():
        item = value.get(key)
        if item is None:
            continue
        if isinstance(item, bool) or not isinstance(item, kinds):
            raise InputError(f"field '{where}.{key}' must be a {kinds[0].__name__}", file=path)
        out[key] = item
    reference = out.get("reference")
    if reference is not None and not (is_number(reference) and reference >= 0):
        raise InputError(f"field '{where}.reference' must be a number of 0 or more", file=path)
    if "sensor" in out and out["sensor"] not in SENSORS:
        raise InputError(f"field '{where}.sensor' must be one of {', '.join(SENSORS)}", file=path)
    columns = out.get("columns")
    if columns is not None and not (
        isinstance(columns, list) and len(columns) == 3 and all(isinstance(c, str) and c for c in columns)
    ):
        raise InputError(f"field '{where}.columns' must be three column names", file=path)
    return cast(Record, out)  # each field checked against RECORD_FIELDS above


#: The reference of a peer file's output units when nothing else says it: 1 for g, and imucal's
#: Ferraris default expected gravity, 9.81, for m/s^2.
REFERENCE_BY_UNITS = {"g": 1.0, "m/s^2": 9.81, "m/s2": 9.81}


class RosYaml:
    """ROS imu_calib's calibration file read back (``tumblecal import --from ros-yaml``); what a
    tumblecal export recorded comes from its data field ``tumblecal``, never from comment text."""

    def claims(self, doc: Mapping[str, object]) -> bool:
        return "SM" in doc and "bias" in doc

    def read(self, doc: Mapping[str, object], path: str, sensor: str | None) -> Peer:
        """``sensor`` None: the recorded one, else an accelerometer."""
        sm = _array(doc.get("SM"), "SM", 9, path).reshape(3, 3)
        bias = _array(doc.get("bias"), "bias", 3, path)
        invertible(sm, path, "SM")
        was = recorded(doc.get("tumblecal"), path, "tumblecal")  # a data field; comments are for people
        # SM raw - bias = SM (raw - SM^-1 bias): offset = SM^-1 bias
        offset = np.asarray(np.linalg.solve(sm, bias), dtype=np.float64)
        # imu_calib calibrates accelerometers, in sensor_msgs/Imu's m/s^2; other sensors' units are unknown
        accel = (sensor or was.get("sensor") or "accelerometer") == "accelerometer"
        return _peer("ros-yaml", sensor, was, offset, sm, "m/s^2" if accel else None, None, ())

    def columns(self, sensor: str) -> list[str]:
        return list("xyz")

    def reference(self, peer: Peer) -> float | None:
        if peer.sensor == "accelerometer":
            return STANDARD_GRAVITY  # imu_calib's do_calib: reference_acceleration defaults to 9.80665
        return REFERENCE_BY_UNITS.get(peer.units or "")


class ImucalJson:
    """imucal's calibration file read back (``tumblecal import --from imucal-json``); what a
    tumblecal export recorded comes from the JSON in its ``comment``."""

    def claims(self, doc: Mapping[str, object]) -> bool:
        return "cal_type" in doc and "K_a" in doc

    def read(self, doc: Mapping[str, object], path: str, sensor: str | None) -> Peer:
        """``sensor`` None: the recorded one, else an accelerometer."""
        return _read_imucal(doc, path, sensor)

    def columns(self, sensor: str) -> list[str]:
        return [f"{'gyr' if sensor == 'gyroscope' else 'acc'}_{a}" for a in "xyz"]

    def reference(self, peer: Peer) -> float | None:
        return REFERENCE_BY_UNITS.get(peer.units or "")


def _read_imucal(doc: Mapping[str, object], path: str, sensor: str | None) -> Peer:
    if doc.get("cal_type") not in ("Ferraris", "TurntableFerraris"):
        raise InputError(
            f"imucal calibration type {doc.get('cal_type')!r} is not one tumblecal reads (Ferraris, TurntableFerraris)",
            file=path,
        )
    version = doc.get("_format_version")
    if version not in IMUCAL_VERSIONS:
        raise InputError(f"imucal format version {version!r} is not one tumblecal reads (1.0.0, 2.0.0)", file=path)
    was = recorded(_comment_record(doc.get("comment"), path), path, "comment.tumblecal")
    sensor = sensor or was.get("sensor") or "accelerometer"
    if sensor == "magnetometer":
        raise InputError("an imucal file holds an accelerometer and a gyroscope, not a magnetometer", file=path)
    slot = "a" if sensor == "accelerometer" else "g"
    k = _array(doc.get(f"K_{slot}"), f"K_{slot}", 9, path).reshape(3, 3)
    r = _array(doc.get(f"R_{slot}"), f"R_{slot}", 9, path).reshape(3, 3)
    b = _array(doc.get(f"b_{slot}"), f"b_{slot}", 3, path)
    invertible(k, path, f"K_{slot}")
    invertible(r, path, f"R_{slot}")
    notes: tuple[str, ...] = ()
    if slot == "g" and np.any(_array(doc.get("K_ga"), "K_ga", 9, path)):
        notes = ("K_ga (the gyroscope's sensitivity to acceleration) has no place in tumblecal's model: left out",)
    units = doc.get(f"{'acc' if slot == 'a' else 'gyr'}_unit")
    raw_units = doc.get(f"from_{'acc' if slot == 'a' else 'gyr'}_unit")
    matrix = np.linalg.inv(r) @ np.linalg.inv(k)  # imucal: R^-1 K^-1 (raw - b)
    if was.get("sensor") != sensor:  # the record describes the other slot
        was = Record()
    raw_units = None if raw_units == "a.u." else _text(raw_units)
    return _peer("imucal-json", sensor, was, b, matrix, _text(units), raw_units, notes)


def _comment_record(comment: object, path: str) -> object:
    """An imucal file's ``comment`` holds a tumblecal export's record as JSON (imucal takes no
    fields of its own beyond its format's, and keeps ``comment`` as it is); another text: none.
    A record that is JSON is read by the rules of a calibration file (no key twice, no lone
    surrogate, no integer past Python's limit): refused there, it is refused here."""
    if not isinstance(comment, str) or not comment.lstrip().startswith("{"):
        return None
    try:
        json.loads(comment)
    except (ValueError, RecursionError):
        return None  # a person's note that starts with a brace
    doc = parse_object(comment.encode("utf-8", "surrogatepass"), path, "tumblecal record in its comment", as_yaml=False)
    return doc.get("tumblecal")


def _peer(
    fmt: str,
    sensor: str | None,
    was: Record,
    offset: FloatArray,
    matrix: FloatArray,
    units: str | None,
    input_units: str | None,
    notes: tuple[str, ...],
) -> Peer:
    return Peer(
        format=fmt,
        sensor=sensor or was.get("sensor") or "accelerometer",
        offset=offset,
        matrix=matrix,
        units=was.get("units", units),
        input_units=was.get("input_units", input_units),
        reference=was.get("reference"),
        columns=was.get("columns"),
        serial=was.get("serial"),
        notes=notes,
        was=was,
    )


def imported(
    peer: Peer,
    *,
    path: str,
    raw: bytes,
    sensor: str,
    reference: float,
    columns: list[str],
    unit: Unit,
) -> Calibration:
    """A format-1 calibration for ``peer`` (method ``imported``; no uncertainty: the
    peer's file does not carry one)."""
    gain = np.diag(np.linalg.inv(peer.matrix))
    was = peer.was  # the original's created and method, when recorded
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "sensor": sensor,
        "method": "imported",
        "reference": reference,
        "units": peer.units,
        "input_units": peer.input_units,
        "columns": columns,
        "offset": [float(v) for v in peer.offset],
        "matrix": [[float(v) for v in row] for row in peer.matrix],
        "gain": [float(v) for v in gain],
        "uncertainty": None,
        "poses": [],
        "imported": {"format": peer.format, "file": path, "sha256": hashlib.sha256(raw).hexdigest()}
        | {k: v for k, v in (("created", was.get("created")), ("method", was.get("method"))) if v},
        "unit": unit.as_dict(),
        "created": created(),
        "tool": f"tumblecal {__version__}",
    }
    return from_dict(doc)


def provenance(cal: Calibration) -> list[str]:
    """Who, when and how, for a comment in an exported file (one fact per line)."""
    unit = (cal.unit or Unit()).as_dict()
    who = ", ".join(f"{k} {unit[k]}" for k in ("serial", "station", "operator") if unit.get(k)) or "no serial"
    verdict = cal.verdict
    judged = ""
    if verdict is not None and (verdict.limit_names or not verdict.passed):
        judged = f", verdict {'PASS' if verdict.passed else 'FAIL'}"
    units = f"{cal.input_units or 'raw units'} in, {cal.units or 'reference units'} out"
    return [
        safe_comment(f"tumblecal {cal.sensor} calibration: {who}"),
        safe_comment(f"created {cal.created or 'unknown'}, method {cal.method}{judged}"),
        safe_comment(f"{units}, reference {float(cal.reference)!r}; columns {', '.join(cal.columns)}"),
    ]


def safe_comment(text: object) -> str:
    """Text safe inside a YAML, MATLAB or parameter file's comment: one line. C0 and C1 controls
    and Unicode's line and paragraph separators become spaces (YAML 1.1 breaks a line at NEL,
    U+2028 and U+2029: what followed would be read as data), and so do U+FFFE and U+FFFF (a YAML
    reader refuses the whole file for one) and lone surrogates (half of a pair: no file holds one)."""
    return re.sub(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\ud800-\udfff\ufffe\uffff]", " ", str(text)).replace("*/", "* /")


def _c_comment(text: str) -> str:
    """Text safe inside a C block comment for any compiler and flags: ASCII only (each other
    character written as ``\\uXXXX`` or ``\\UXXXXXXXX``, a backslash as ``\\\\``), and no ``/*``,
    ``*/`` or ``??`` (a trigraph in C99: ``??/`` is a backslash) left in it: a space goes between
    the two characters. gcc -std=c99 -Wall -Wextra -Werror -pedantic compiles it for any text."""
    text = safe_comment(text).replace("\\", "\\\\")
    text = "".join(
        c if " " <= c <= "~" else f"\\u{ord(c):04x}" if ord(c) < 0x10000 else f"\\U{ord(c):08x}" for c in text
    )
    return re.sub(r"(/(?=\*)|\*(?=/)|\?(?=\?))", r"\1 ", text)


def _yaml_flow(value: object) -> str:
    """``value`` as JSON that YAML reads back as the same value: JSON's ``\\ud83d\\ude00`` (a
    pair of surrogates for one character beyond the BMP) YAML reads as two halves, so every
    character that is not printable ASCII is written as YAML's ``\\uXXXX`` or ``\\UXXXXXXXX``
    (only JSON's strings hold such characters, JSON having escaped those below a space: the
    escapes are in double-quoted scalars)."""
    text = json.dumps(value, ensure_ascii=False)
    return "".join(c if ord(c) < 0x7F else f"\\u{ord(c):04x}" if ord(c) < 0x10000 else f"\\U{ord(c):08x}" for c in text)


def _c_float(value: float, name: str, path: str | None) -> str:
    if not abs(value) <= FLOAT32_MAX:
        raise InputError(f"{name} = {float(value):g} does not fit in a C float", file=path)
    text = str(np.float32(value))  # the shortest text that reads back as the same float
    return (text if any(c in text for c in ".e") else text + ".0") + "f"


def _array(value: object, name: str, size: int, path: str) -> FloatArray:
    flat = np.array(value, dtype=object).ravel() if isinstance(value, list) else None
    if flat is None or flat.size != size or not all(is_number(v) for v in flat):
        shape = {3: "3 numbers", 9: "3x3 numbers"}[size]
        raise InputError(f"field {name!r} must be {shape}", file=path)
    return flat.astype(np.float64)


def _text(value: object) -> str | None:
    return value if isinstance(value, str) else None


# -- the registry's rows (io.export.registry) ----------------------------------------------


def export_c_header(cal: Calibration, options: ExportOptions) -> Exported:
    return Exported(c_header(cal, prefix=options.prefix))


def export_imucal_json(cal: Calibration, options: ExportOptions) -> Exported:
    return Exported(imucal_json(cal))


def export_ros_yaml(cal: Calibration, options: ExportOptions) -> Exported:
    return Exported(ros_yaml(cal))


def export_matlab(cal: Calibration, options: ExportOptions) -> Exported:
    return Exported(matlab(cal))


#: The export formats of this module, by their names in io.export.registry.EXPORTS.
EXPORTERS: dict[str, Exporter] = {
    "c-header": export_c_header,
    "registers": export_registers,
    "imucal-json": export_imucal_json,
    "ros-yaml": export_ros_yaml,
    "matlab": export_matlab,
}
#: The import formats of this module, by their names in io.export.registry.IMPORTS.
IMPORTERS: dict[str, Importer] = {"imucal-json": ImucalJson(), "ros-yaml": RosYaml()}
