"""Driving the table. One idea per module:

- :mod:`.schedule`    calibration schedules as data (TOML); ready-made ones in ``schedules/``
- :mod:`.controller`  the calibration controller: a Python unit that walks a schedule
- :mod:`.sequencer`   a minimal attitude sequencer unit (the tumble example)
"""
