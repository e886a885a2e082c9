"""The numeric core, numpy only: no files, no terminal, no pandas; every formula cites its source
(docs/sources.md). It names no command-line flag: the words about the command line in its errors,
findings and notes are said by a code and its facts (errors.said), worded by pipeline.hints. Its
modules:

- ``arrays``: the array types the signatures name (FloatArray, IntArray, BoolArray), defined once.
- ``model``: faces and pose labels, pose statistics, the measurement model, the 1- and 3-pose
  solvers, tilt sensitivity, and apply (``M (raw - b)``).
- ``solvers``: the solvers beyond 1- and 3-pose (six-pose, least squares, sphere, tilt-compensated
  1-pose, magnetometer min/max and ellipsoid, gyroscope bias).
- ``catalog``: the solvers there are, one row each: what it takes and fits, the limits that do
  not apply to it, its source, its function (numpy-free: the command line's ``--method``).
- ``fits``: each catalog row's function (one input in, a fit out) and the dispatch through the
  rows.
- ``robust``: the trimmed refit that keeps outliers (glitch rows, disturbed stretches) out of a
  fit over samples, and the stretches it left out.
- ``methods``: which solver: ``auto`` resolved from the labels and the sensor, each method's
  labels checked, and the evidence that chooses between six-pose and six-pose-magnitude.
- ``gate``: the production-test gate: quality checks on each pose (exit 3), limits and the
  verdict (exit 1).
- ``running``: a long pose's readings as running sums, the statistics every check needs.
- ``blocks``: the still blocks of a log held in memory (or its pose labels), judged and
  labelled with the faces they show.
- ``scan``: the same still-block detection fed a log block by block, keeping only the still
  periods' spreads.
- ``chunks``: a long log's readings as sums over chunks, merged into each block's statistics.
- ``clock``: a log's clock: seconds per sample, gaps, and stamps taken on arrival.
- ``stillness``: where a gyroscope is still, cut down from the accelerometer's still blocks.
- ``alignment``: the rotation between two sensors' axes from still blocks seen by both.
- ``axes``: a sensor's axes stated in the body's (``--axes -y,-x,+z``): a signed permutation.
- ``earth``: the Earth's reference fields at a place: normal gravity and the magnetic model.
- ``quantities``: the unit names tumblecal knows, the quantity each measures and its factor to the
  quantity's base unit; standard gravity.
- ``drift``: offset and gain drift fitted against temperature, and each row corrected at its
  own temperature.
- ``current_fit``: a magnetometer's offset per ampere of motor current.
- ``turn_fit``: a gyroscope's bias, g-sensitivity, scale and misalignment from known turns (the
  Ferraris procedure).
- ``rotation_fit``: a gyroscope's scale and misalignment from hand turns between still poses,
  gravity the reference.
- ``spin``: a gyroscope's offset, gains and cross-axis terms from steady runs at known rates (a
  rate table, a record player), and its scale factors by rate.
- ``allan``: the Allan deviation of a still capture, computed as it streams, and the noise
  figures read off it.
- ``lot``: statistics over a production lot of calibrations: which files count, capability and
  outliers per parameter, and each re-calibrated unit's drift.
- ``outliers``: outlier flags over a lot that hold the lot-wide false-alarm rate.
- ``control``: control charts of a station's calibrations over time (individuals, EWMA, the
  Western Electric rules with limits that hold a run's false-alarm rate), stations compared."""
