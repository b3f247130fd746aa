"""Test FMU: an integer counter, n = n_in + mode * (doStep calls so far), for integer
connections and integer start values (libcosim's limits, verify's exact comparison)."""
from fmus.modeldef import ModelTable, integer, real

TABLE = ModelTable(
    identifier="test_counter",
    description="n = n_in + mode * steps",
    variables=[
        real("y", "output", None, "1", "the count as a real"),
        integer("mode", "parameter", 1, "count step (rewritten into an Enumeration by a test)"),
        integer("n_in", "input", 0, "offset added to the count"),
        integer("n", "output", None, "n_in + mode * steps"),
    ],
    sources=["model.c"],
    can_interpolate_inputs=False,
)
