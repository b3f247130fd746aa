"""Test FMU: y = t; the step that starts at fail_time returns fmi2Error with a logged reason."""
from fmus.modeldef import ModelTable, real

TABLE = ModelTable(
    identifier="test_failing",
    description="fails deliberately at fail_time",
    variables=[
        real("fail_time", "parameter", 1e300, "s", "start time of the step that fails"),
        real("u", "input", 0.0, "1", "ignored input"),
        real("y", "output", None, "s", "time at the end of the step"),
    ],
    sources=["model.c"],
    can_interpolate_inputs=False,
)
