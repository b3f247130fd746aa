"""Simulating calibration runs on the plant FMUs. One idea per module:

- :mod:`.roles`      the ``turntable`` and ``imu`` roles and the ``builtin:`` FMU scheme
- :mod:`.scenario`   scenario files: schedule, FMUs, injected effects and noise, site, step
- :mod:`.run`        a scenario built and run: the log and its truth
- :mod:`.replay`     a log's motion replayed through an IMU unit, its commands through a table
- :mod:`.multi_imu`  several IMUs on one table in one run
- :mod:`.tumble`     the one-minute check of the two FMUs
"""
