"""calbench's domain: roles, calibration controller, procedures, estimators, effects, diagnosis,
campaigns and reports. Importing the package registers the plant roles with the orchestrator."""
from components import roles as _roles  # noqa: F401
