"""Files. Errors name the file, line and column. Its modules:

- ``readspec``: how to read a source (``ReadSpec``: the sensor, its columns, the clock, the
  file's dialect), one value from the command line down to every reader.
- ``sniff``: a CSV capture's layout decided from its head: delimiter, header, preamble, decimal
  mark, and which columns hold the sensor triplet, the time and the temperature.
- ``capture``: a CSV capture streamed through pyarrow with every cell's text kept, and its
  errors located by line and column (docs/reference/csv.md).
- ``sources``: where a reader of another kind of file (a binary log) plugs in: a ``Reader``
  claims a file and gives its readings as a ``Table``; every command then takes it.
- ``readings``: pose files and whole logs read into memory (``Samples``, ``Log``), with their
  clock's unit judged.
- ``rewrite``: apply's streaming writer: a capture written again with its sensor columns
  corrected and every other byte kept.
- ``splice``: apply's fast path, corrected sensor cells spliced into a plain file's own bytes.
- ``forked``: apply's blocks corrected by forked worker processes, one per core.
- ``logread``: a long log read block by block into the streaming still-block detector
  (``core.scan``), for segment and solve --log.
- ``calfile``: the typed Calibration and its JSON/YAML form (docs/reference/calibration-file.md).
- ``calparts``: its typed parts (poses, verdict, tilt sensitivity, residuals, thermal ...), each
  read from and written to its field.
- ``documents``: a JSON or YAML document read safely (size, encoding, duplicate keys, aliases).
- ``limitfile``: limits files: the bounds a unit is judged by.
- ``formats``: a calibration in other tools' terms (firmware, imucal, ROS, MATLAB, ArduPilot,
  PX4) for export, and imucal/ROS files read back for import.
- ``outputs``: atomic writes, '-' for stdout, and the rule that no command writes onto an input.
- ``plots``: PNG figures for --plot (the optional extra ``tumblecal[plot]``)."""
