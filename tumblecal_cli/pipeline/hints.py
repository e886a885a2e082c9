"""The words about the command line that the core's errors, findings and notes say: one row per
code, a ``str.format`` template of the facts the core gives (errors.Said). The core names no flag
(tests/test_hints.py holds it to that, and every code it says to a row here); the package's import
installs this table (tumblecal_cli/__init__), so the Python API reads the same text as the command
line, and ``err.said`` gives the code and its facts to a caller that would say them its own way.
"""

from __future__ import annotations

#: Each code the core says, and its words. Grouped by the core module that says it.
WORDS: dict[str, str] = {
    # core.gate: the quality checks, the coverage check, gains in other units
    "pose.short": "fewer than --min-samples {least}",
    "pose.short.close": "close to --min-samples {least}",
    "pose.saturated.level": "{fraction:.0%} of --full-scale {full_scale:g}",
    "pose.orientation.close": "close to --max-tilt {tilt:g}°",
    "pose.orientation.tilt": "more than --max-tilt {tilt:g}°",
    "pose.orientation.centre": "raw counts around a common centre need --nominal-offset (e.g. 32768)",
    "pose.orientation.centre.hint": "give the raw reading at zero stimulus with --nominal-offset "
    "(unsigned 16-bit counts: 32768)",
    "pose.moved": "--max-noise",
    "pose.moved.rule": "--max-noise {rule}",
    "poses.coverage.minmax": "drop --method minmax (the ellipsoid fit takes faces up to {reach:.0f}° away)",
    "poses.coverage.keep": "keep this fit with --no-check coverage",
    "gains.near_one": "the gains are near 1, as for data in the units of --reference: check --nominal-gain "
    "(or the limits file's nominal_gain)",
    "gains.units": "the data looks like {units}: {verb} with --reference {reference:g}",
    "gains.counts": "the data looks like raw counts (about {typical:.4g} per unit of --reference): give "
    "--nominal-gain {gain:g} to judge the gains as counts per unit, or --reference {reference:g} to keep the "
    "output in counts",
    "units.asked": "as --reference {reference:g} asks",
    "units.again.si": "--reference {gravity:g} --units m/s^2",
    "units.again.g": "--reference 1",
    # core.model, core.solvers: the solvers' settings
    "three.reference": "the 3-pose solver needs a positive --reference (the stimulus magnitude)",
    "fit.reference": "the {fit} fit needs a positive --reference",
    "poses.tilted": "rest the unit flat on each face, or capture 12 or more orientations for --method sphere",
    "tilt.bounded": "bounded by --bias-spread {spread:g}",
    "plane.turned": "give --plane {turned}, or turn the unit a full circle in the {plane} plane",
    # core.methods: which solver takes the poses given
    "poses": "--poses",
    "faces.missing": "every axis needs a pose with it pointing up or down: one face per axis solves as "
    "three-pose (e.g. --poses -z=a.csv -x=b.csv +y=c.csv), four or more as least-squares",
    "poses.none": "label a file with its face or direction: --poses +x=a.csv -x=b.csv 0.707,0,0.707=c.csv",
    "gyro.sensor": "gyro-bias is a gyroscope's zero-rate bias: give --sensor gyroscope (not {sensor})",
    "up.missing": "{method} needs the face pointing up: label the file (+z=z.csv) or give --up",
    "up.face": "label it with a face (+z=z.csv) or give the face with --up",
    "three.labels": "label each file with the face that was up, e.g. --poses -z=a.csv -x=b.csv +y=c.csv (see --help)",
    "six.labels": "label each file with its face, e.g. --poses +x=xp.csv -x=xn.csv ... (see --help)",
    "least.labels": "label each file: --poses +x=a.csv 0.707,0,0.707=b.csv ...",
    "auto.magnitude": "--method six-pose fits them anyway",
    # core.blocks, core.clock: a log's still blocks and its clock
    "clock.wrong": "give the time column's unit (--time-unit ms, us or ns) or the sample rate (--rate HZ)",
    "clock.bursty": "give --rate HZ if it is not",
    "blocks.mislabelled": "check --pose-map",
    "blocks.unnamed": "map one with --pose-map LABEL={face}",
    "blocks.short": "below --min-duration {limit}",
    "blocks.noisy": "see --max-noise",
    "blocks.tilted": "beyond --max-tilt {tilt:g}°",
    # core.lot, core.outliers: report's lot-wide settings
    "drift.empty": "--max-drift is empty",
    "drift.item": "--max-drift {item!r} is not KEY=VALUE",
    "drift.key": "--max-drift: unknown key {key!r} (known: {known})",
    "drift.twice": "--max-drift: {key!r} is given twice",
    "drift.number": "--max-drift: {key}={value!r} is not a number",
    "drift.positive": "--max-drift: {key} must be a positive number, got {value!r}",
    "drift.hint": "--max-drift offset=0.01,gain=0.002 (offset in raw units; gain and cross as fractions)",
    "outliers.alpha": "--outlier-alpha must be a probability between 0 and 1 (exclusive), got {alpha}",
}
