"""A calibration in other tools' terms (``tumblecal export`` and ``import``). Its modules:

- ``formats``: firmware (C header, offset registers), imucal, ROS and MATLAB for export, and
  imucal/ROS files read back for import.
- ``paramfile``: autopilot parameter files: ArduPilot ``.parm`` and PX4 ``.params``."""
