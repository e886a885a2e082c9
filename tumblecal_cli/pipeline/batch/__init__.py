"""batch: the units of a lot, each solved, and the summary. Its modules:

- ``units``: the units found (a folder or a manifest), each solved and published, and the run.
- ``cluster``: where the units run: in process, in worker processes, or on a Dask cluster (and
  apply over many files).
- ``summary``: summary.csv, one row per unit, written as each finishes and read back for
  ``--resume``."""
