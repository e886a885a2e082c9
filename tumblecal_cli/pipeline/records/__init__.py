"""Calibration records: every unit's calibration kept in a database, every station watched over
time (docs/records.md). ImportDone only by a run that records or reads records: a command without
``--record`` loads none of it (nor ``sqlite3``). Its modules:

- ``columns``: a calibration as one row: its typed columns (serial, station, ... each offset, gain
  and cross-axis term) beside the whole document, and its content key.
- ``store``: the database: its versioned schema, opened and refused safely, written in
  transactions with parameters only.
- ``recording``: ``--record``: the record and the output file published together, both or neither.
- ``history``: a unit's records, newest first, with what changed between them.
- ``importing``: existing calibration files and batch folders taken in, each once.
- ``trend``: each station's parameters charted over time (``core.control``), the alarms named.
"""
