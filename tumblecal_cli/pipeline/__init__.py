"""What a user does, composed from io and core: the public Python API (``tumblecal_cli.__all__``)
that the commands, ``batch`` and the Dask workers call. pandas only inside the functions that take
or return DataFrames. Its modules:

- ``solve``: pose captures (or one continuous log) in, a judged Calibration out.
- ``options``: solve's options (and those the commands share), checked and resolved once.
- ``logs``: continuous logs: their still blocks found, the poses a solver needs picked (solve
  --log), and one CSV written per block (segment).
- ``turns``: a gyroscope calibrated from one labelled log of the Ferraris procedure (solve --turns).
- ``rotations``: a gyroscope's scale and misalignment from hand turns in a log (solve
  --accel-cal).
- ``correct``: apply: captures corrected with one or more calibrations, streamed file to file.
- ``batch``: batch: the units of a lot, each solved, and the summary.
- ``cluster``: where many units or captures run: in process, in worker processes, or on a Dask
  cluster (batch, and apply over many files).
- ``thermal``: temperature sweeps in, a calibration with a ``thermal`` block out.
- ``current``: magnetometer logs with a motor-current column in, a calibration with a
  ``current`` block (its offset per ampere) out.
- ``verify``: a calibration checked on static captures (a gyroscope's: on a log of hand turns)
  it was not fitted on.
- ``noise``: the Allan deviation of a still capture and its noise figures, judged against limits
  and written as the noise model Kalibr and VINS read.
- ``report``: a lot's calibration files found, read and summarised (``core.lot``).
- ``exchange``: calibration files after solve: checked again, exported to firmware or another
  tool, imported from one.
- ``frames``: the Python API's data in memory: DataFrames and (n, 3) arrays in, DataFrames out."""
