"""Where the FMU a system names lives: ``fmu = "<scheme>:<name>"`` goes through a resolver
registered for the scheme, anything else is a path.

A leaf module: the orchestrator stays domain-free because the schemes (``builtin:`` for the
project's own FMUs) are registered from outside, and both the master (loading units) and the
SSP writer (copying FMUs into an archive) resolve names without importing each other.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from orchestrator.errors import SystemError_
from orchestrator.plugins import load_plugins

_FMU_RESOLVERS: dict[str, Callable[[str], Path]] = {}


def register_fmu_resolver(scheme: str, resolver: Callable[[str], Path]) -> None:
    """``fmu = "<scheme>:<name>"`` in a system file resolves through ``resolver(name)``."""
    _FMU_RESOLVERS[scheme] = resolver


def resolve_fmu(spec: str, base_dir: Path) -> Path:
    """The FMU file a system names: ``<scheme>:<name>`` through a registered resolver, else a
    path (relative to *base_dir*)."""
    scheme, _, rest = spec.partition(":")
    if rest and scheme not in _FMU_RESOLVERS and not Path(spec).exists():
        load_plugins()
    if rest and scheme in _FMU_RESOLVERS:
        try:
            return Path(_FMU_RESOLVERS[scheme](rest))
        except (KeyError, ValueError) as e:   # a name the scheme does not know
            raise SystemError_(f"fmu = {spec!r}: {str(e).strip(chr(39))}") from None
    p = Path(spec)
    return p if p.is_absolute() else base_dir / p
