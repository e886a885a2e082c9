"""tumblecal: calibrate 3-axis sensors from static tumble poses and correct captures.

Layers (imports flow one way): ``cli`` -> ``captures``/``calfile`` (io) -> ``core`` (numpy only).
Nothing here imports numpy or pyarrow, so ``tumblecal --help`` stays fast.
"""

__version__ = "0.1.0"
