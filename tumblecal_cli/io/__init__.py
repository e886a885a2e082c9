"""Files. Errors name the file, line and column. Its modules:

- ``captures``: CSV captures in and out, one set of rules (README "CSV captures"): the layout
  sniffed, the sensor columns read, and corrected captures written with every other cell kept.
- ``splice``: apply's fast path, corrected sensor cells spliced into a plain file's own bytes.
- ``forked``: apply's blocks corrected by forked worker processes, one per core.
- ``logread``: a long log read block by block into the streaming still-block detector
  (``core.scan``), for segment and solve --log.
- ``calfile``: the typed Calibration and its JSON/YAML form (README "Calibration file"); limits
  files.
- ``formats``: a calibration in other tools' terms (firmware, imucal, ROS, MATLAB, ArduPilot,
  PX4) for export, and imucal/ROS files read back for import.
- ``outputs``: atomic writes, '-' for stdout, and the rule that no command writes onto an input.
- ``plots``: PNG figures for --plot (the optional extra ``tumblecal[plot]``)."""
