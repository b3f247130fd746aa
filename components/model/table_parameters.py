"""Table effects of the vocabulary (``table.base_tilt``, ``table.base_azimuth``, ``table.nonorth``, ``table.wobble``,
``table.encoder``, ``table.reversal``) as fields of a
:class:`~components.model.geometry.TableGeometry`: a parameter name of the vocabulary set on, or
read from, the geometry."""
from __future__ import annotations

from dataclasses import replace

from components.model.geometry import TableGeometry

# effect -> the field of a Stage ({c}: the parameter's last index); base_tilt is the geometry's
_STAGE_FIELD = {"table.nonorth": "nonorth_{c}", "table.wobble": "wobble_{c}", "table.encoder": "enc_{c}",
                "table.reversal": "reversal"}


def _field(name: str) -> tuple[str | None, str]:
    """(the stage a parameter belongs to, or None for the base; the field that holds it):
    ``table.base_tilt.x`` -> (None, "tilt_x"), ``table.encoder.outer.s1`` -> ("outer", "enc_s1"),
    ``table.reversal.middle`` -> ("middle", "reversal"), ``table.base_azimuth`` -> (None, "azimuth")."""
    parts = name.split(".")
    effect = ".".join(parts[:2])
    if effect == "table.base_tilt":
        return None, f"tilt_{parts[2]}"
    if effect == "table.base_azimuth":
        return None, "azimuth"
    return parts[2], _STAGE_FIELD[effect].format(c=parts[-1])


def table_stage(name: str) -> str | None:
    """The stage a table-effect parameter belongs to, or None for the base's (tilt, azimuth)."""
    return _field(name)[0]


def apply_table_parameter(geo: TableGeometry, name: str, value: float) -> TableGeometry:
    """Geometry with one table-effect parameter set (names of components.model.effects)."""
    stage, attr = _field(name)
    if stage is None:
        return replace(geo, **{attr: value})
    if stage not in geo.names:
        return geo  # a stage this table does not have: the parameter has no effect
    return geo.with_stage(stage, **{attr: value})


def table_parameter_value(geo: TableGeometry, name: str) -> float:
    """The value of one table-effect parameter in a geometry (0 for a stage it does not have)."""
    stage, attr = _field(name)
    if stage is None:
        return getattr(geo, attr)
    if stage not in geo.names:
        return 0.0
    return getattr(next(s for s in geo.stages if s.name == stage), attr)
