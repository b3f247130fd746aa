"""Test FMU: y = u with direct feed-through, declared in the ModelStructure (depends_on)."""
from fmus.modeldef import ModelTable, real

TABLE = ModelTable(
    identifier="test_feedthrough",
    description="y = u, instantaneously (direct feed-through)",
    variables=[
        real("u", "input", 0.0, "1", "input"),
        real("y", "output", None, "1", "output, equal to u at every instant", depends_on=["u"]),
    ],
    sources=["model.c"],
    can_interpolate_inputs=False,
)
