"""Files: ``captures`` (CSV in and out), ``calfile`` (the typed Calibration and its JSON/YAML
form; limits files), ``formats`` (other tools' calibration files), ``outputs`` (atomic writes)
and ``plots`` (PNG figures). Errors name the file, line and column."""
