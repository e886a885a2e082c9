"""What a user does, composed from io and core: the public Python API (``tumblecal_cli.__all__``)
that the commands, ``batch`` and the Dask workers call. pandas only inside the functions that take
or return DataFrames. A command's module is named after the command. Its rooms and modules:

- ``solve/``: pose captures, tables or one continuous log in, a judged Calibration out.
- ``batch/``: the units of a lot, each solved where it runs best, and the summary.
- ``records/``: calibrations kept in a database, each unit's history, each station's trend.
- ``options``: solve's options (and those the commands share), checked and resolved once.
- ``frames``: the Python API's data in memory: DataFrames and (n, 3) arrays in, DataFrames out.
- ``places``: where a unit was calibrated: the local gravity and Earth's field, by place and date.
- ``segment``: continuous logs: their still blocks found and judged, the poses a solver needs
  picked (solve --log), and one CSV written per block (segment).
- ``align``: one sensor's axes rotated onto another's from the still blocks they share.
- ``apply``: captures corrected with one or more calibrations, streamed file to file.
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
- ``hints``: the words about the command line (its flags) that the core's errors, findings and
  notes say by a code: one table, installed by the package's import.
- ``plotting``: the figures a command's ``--plot`` draws, from what the pipeline returned."""
