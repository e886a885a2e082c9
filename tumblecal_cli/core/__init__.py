"""The numeric core, numpy only: ``model`` (faces, pose statistics, the measurement model, 1- and
3-pose solvers, apply), ``solvers`` (six-pose to ellipsoid), ``gate`` (quality checks, limits and
the verdict), ``segment`` (still blocks of a log) and ``lot`` (lot statistics). No files, no
terminal, no pandas; every formula cites its source (README "Sources")."""
