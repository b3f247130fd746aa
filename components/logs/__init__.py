"""Measurement logs in the ``calbench-log/1`` format (docs/measurement-log.md). One idea per
module:

- :mod:`.rules`      the format's rules: metadata keys, columns, time, checked with clear errors
- :mod:`.logfile`    reading and writing a log (CSV or Parquet plus JSON metadata)
- :mod:`.recording`  a log from an orchestrator recording of the turntable and IMU units
- :mod:`.spill`      a long log's sensor columns memory-mapped from a temporary file, and the
                     passes over them a piece at a time
"""
