"""Table effects of the vocabulary (``table.base_tilt``, ``table.nonorth``, ``table.wobble``,
``table.encoder``, ``table.reversal``) as fields of a :class:`~components.model.geometry.TableGeometry`: a parameter
name of the vocabulary set on, or read from, the geometry."""
from __future__ import annotations

from dataclasses import replace

from components.model.geometry import TableGeometry


def apply_table_parameter(geo: TableGeometry, name: str, value: float) -> TableGeometry:
    """Geometry with one table-effect parameter set (names of components.model.effects)."""
    parts = name.split(".")
    if name.startswith("table.base_tilt."):
        return replace(geo, **{f"tilt_{parts[2]}": value})
    if name.startswith("table.reversal."):
        return geo.with_stage(parts[2], reversal=value) if parts[2] in geo.names else geo
    axis, comp = parts[2], parts[3]
    if axis not in geo.names:
        return geo  # a stage this table does not have: the parameter has no effect
    field_name = {"table.nonorth": f"nonorth_{comp}", "table.wobble": f"wobble_{comp}",
                  "table.encoder": f"enc_{comp}"}[".".join(parts[:2])]
    return geo.with_stage(axis, **{field_name: value})


def table_parameter_value(geo: TableGeometry, name: str) -> float:
    """The value of one table-effect parameter in a geometry (0 for a stage it does not have)."""
    parts = name.split(".")
    if name.startswith("table.base_tilt."):
        return getattr(geo, f"tilt_{parts[2]}")
    axis = parts[2]
    if axis not in geo.names:
        return 0.0
    stage = next(s for s in geo.stages if s.name == axis)
    if name.startswith("table.reversal."):
        return stage.reversal
    comp = parts[3]
    attr = {"table.nonorth": f"nonorth_{comp}", "table.wobble": f"wobble_{comp}",
            "table.encoder": f"enc_{comp}"}[".".join(parts[:2])]
    return getattr(stage, attr)
