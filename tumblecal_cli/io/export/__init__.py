"""A calibration in other tools' terms (``tumblecal export`` and ``import``). Its modules:

- ``registry``: where a format plugs in: one registry of export and of import formats (the
  command line's ``--format`` and ``--from`` choices), each format's module loaded when it is used.
- ``contract``: the ``Exporter`` and ``Importer`` contracts a format keeps, and the values they
  pass (``ExportOptions``, ``Exported``, ``Peer``).
- ``formats``: firmware (C header, offset registers), imucal, ROS and MATLAB for export, and
  imucal/ROS files read back for import.
- ``paramfile``: autopilot parameter files: ArduPilot ``.parm`` and PX4 ``.params``."""
