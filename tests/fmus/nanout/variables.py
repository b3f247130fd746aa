"""Test FMU: y = t, but NaN from the end of the step that reaches nan_time (logged as a
warning, the step itself returns OK: only the master's output check can catch it)."""
from fmus.modeldef import ModelTable, real

TABLE = ModelTable(
    identifier="test_nanout",
    description="emits NaN from nan_time on",
    variables=[
        real("nan_time", "parameter", 1e300, "s", "end time of the first step whose output is NaN"),
        real("y", "output", None, "s", "time at the end of the step, or NaN"),
    ],
    sources=["model.c"],
    can_interpolate_inputs=False,
)
