"""calbench's domain: roles, calibration controller, procedures, estimators, effects, diagnosis,
campaigns and reports. Importing the package registers the plant roles with the orchestrator."""
import os as _os

# One BLAS thread: a multi-threaded BLAS sums in an order that depends on the thread count, which
# changes the last bit of covariances between a CLI run, a campaign worker and a test; calbench's
# matrices are small, so the same bits everywhere cost nothing. (Effective when calbench is
# imported before numpy, as the CLI and the campaign workers do.)
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_v, "1")

from components import roles as _roles  # noqa: E402,F401
