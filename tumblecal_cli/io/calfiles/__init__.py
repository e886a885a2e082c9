"""Calibration documents (docs/reference/calibration-file.md). Its modules:

- ``calfile``: the typed ``Calibration`` and its JSON/YAML form (a ``dict`` only there).
- ``calparts``: its typed parts (poses, verdict, tilt sensitivity, residuals, thermal ...), each
  read from and written to its field.
- ``documents``: a JSON or YAML document read safely (size, encoding, duplicate keys, aliases).
- ``limitfile``: limits files: the bounds a unit is judged by."""
