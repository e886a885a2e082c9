"""solve: captures in, a judged Calibration out. Its modules:

- ``solving``: the entry points (``solve``, ``solve_log``, ``calibrate``): poses read, averaged,
  solved, checked and judged.
- ``fitnotes``: what solve says of a fit beyond its parameters: the samples a robust fit left
  out, a fit that holds the motion's acceleration, a reference that does not fit its units.
- ``tables``: a table of orientations, one averaged reading a row, split into poses.
- ``trimming``: pose files with motion solved from their still run.
- ``maglog``: a magnetometer from a log with both sensors, and its dip check.
- ``turns``: a gyroscope from one labelled log of the Ferraris procedure (solve --turns).
- ``rotations``: a gyroscope's scale and misalignment from hand turns (solve --accel-cal).
- ``spins``: a gyroscope spun at known rates (solve --spin RATE=FILE): its files' steady runs
  fitted, what was left out named by rows."""
