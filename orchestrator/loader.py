"""Reading a system file, whatever its format: the suffix picks the reader (``.ssp``: an SSP
archive, anything else: TOML) and both give the same :class:`~orchestrator.system.System`.

This module sits above the readers so that the system model (``system.py``) does not import
the SSP reader, which itself builds on the model.
"""
from __future__ import annotations

from pathlib import Path

from orchestrator.errors import SystemError_
from orchestrator.ssp_load import load_ssp
from orchestrator.system import System, load_toml_system


def load_system(path: str | Path) -> System:
    """The :class:`System` in the file at *path* (TOML, or SSP when it ends in ``.ssp``)."""
    p = Path(path)
    if p.is_dir():
        raise SystemError_(f"{p}: a directory; expected a system file (.toml or .ssp)")
    if not p.exists():
        raise SystemError_(f"{p}: no such system file (.toml or .ssp)")
    if p.suffix.lower() == ".ssp":
        return load_ssp(p)
    return load_toml_system(p)
