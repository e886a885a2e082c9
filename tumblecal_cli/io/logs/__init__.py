"""Autopilot and robot logs, each a reader registered in ``io.sources``. Its modules:

- ``fields``: what the binary readers share: a sensor's columns, fixed-layout fields gathered
  a chunk at a time, a clock that must go forward.
- ``ulog``: PX4 ULog (``.ulg``).
- ``dataflash``: ArduPilot DataFlash binary logs (``.bin``).
- ``dftext``: ArduPilot DataFlash logs in their text form (``.log``).
- ``ros``: ROS 1 bags, ROS 2 bags and MCAP files (the optional extra ``tumblecal[ros]``)."""
