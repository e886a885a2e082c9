"""A calibration in other tools' terms (``tumblecal export`` and ``import``). Its modules:

- ``registry``: where a format plugs in: the ``Exporter`` and ``Importer`` contracts, one
  registry of each (the command line's ``--format`` and ``--from`` choices), each format's
  module loaded when it is used.
- ``formats``: firmware (C header, offset registers), imucal, ROS and MATLAB for export, and
  imucal/ROS files read back for import.
- ``paramfile``: autopilot parameter files: ArduPilot ``.parm`` and PX4 ``.params``."""
