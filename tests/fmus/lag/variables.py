"""Test FMU: first-order lag tau y' = u - y, exact discretisation with u held over the step;
also counts its steps and reports the last step size (for multi-rate checks)."""
from fmus.modeldef import ModelTable, real

TABLE = ModelTable(
    identifier="test_lag",
    description="first-order lag, exact for an input held over each step",
    variables=[
        real("tau", "parameter", 1.0, "s", "time constant"),
        real("y0", "parameter", 0.0, "1", "initial output"),
        real("u", "input", 0.0, "1", "input, held over the step"),
        real("y", "output", None, "1", "lag output at the end of the step"),
        real("steps", "output", None, "1", "number of doStep calls so far"),
        real("h_last", "output", None, "s", "size of the last step (0 before the first)"),
    ],
    sources=["model.c"],
    can_interpolate_inputs=False,
)
