"""calbench's domain, in packages that depend one way, left to right:

    errors → model → logs → estimation → diagnosis → control → simulation
           → procedures → navigation → campaign → cli

- ``errors``      every error a user may see (a leaf: imports nothing)
- ``model``       the effect vocabulary, table geometry, plate motion, a calibrated model
- ``logs``        calbench-log/1 measurement logs: rules, reading, writing, from recordings
- ``estimation``  observation blocks, the design, least squares, the Cramér–Rao bound
- ``diagnosis``   model against measurement: compare, diagnose, the ladder, the report
- ``control``     schedules and the calibration controller that walks them on the table
- ``simulation``  the plant roles, scenarios (run on the FMUs), replay, tumble
- ``procedures``  the seeds' classical procedures
- ``navigation``  system-level calibration: strapdown navigation and the Kalman filter
- ``campaign``    certification-style test campaigns on Dask
- ``cli``         the ``calbench`` command: dispatch only

``docs/architecture.md`` says what flows between them and where new work goes.
"""
import os as _os

# One BLAS thread: a multi-threaded BLAS sums in an order that depends on the thread count, which
# changes the last bit of covariances between a CLI run, a campaign worker and a test; calbench's
# matrices are small, so the same bits everywhere cost nothing. (Effective when calbench is
# imported before numpy, as the CLI and the campaign workers do.)
ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
for _v, _n in ONE_BLAS_THREAD.items():
    _os.environ.setdefault(_v, _n)
