"""Files: every source read in, every file written out. Errors name the file, line and column.
Its rooms and modules:

- ``readspec``: how to read a source (``ReadSpec``: the sensor, its columns, the clock, the
  file's dialect), one value from the command line down to every reader, made of the Python
  API's keywords (``ReadKeywords``) in one place (``read_spec``).
- ``sources``: where a reader of another kind of file (a binary log) plugs in: the ``Reader``
  contract, the registry of readers, and ``streams``.
- ``outputs``: atomic writes, '-' for stdout, and the rule that no command writes onto an input.
- ``csv/``: CSV captures: their layout sniffed, streamed with every cell kept, read into memory
  as pose files and whole logs, and a long log read block by block.
- ``logs/``: autopilot and robot logs (PX4 ULog, ArduPilot DataFlash, ROS bags and MCAP).
- ``calfiles/``: the calibration file, its typed parts, safe JSON/YAML documents and limits files.
- ``export/``: a calibration in other tools' and firmware's terms, and peer files read back.
- ``figures/``: PNG figures and the lot's HTML page (the optional extra ``tumblecal[plot]``).
- ``rewrite/``: apply's writer: a capture written again with its sensor columns corrected."""
