"""Roles and FMU schemes that other packages contribute, found through the installed packages'
entry points (group ``orchestrator.plugins``: a callable that registers them).

The orchestrator knows no domain: calbench's ``turntable`` and ``imu`` roles and its
``builtin:`` FMUs come from ``components`` this way, so a system file that names them runs
whoever imports the orchestrator first. Loaded once, the first time a role or scheme is looked up
that is not registered yet.
"""
from __future__ import annotations

from importlib.metadata import entry_points

GROUP = "orchestrator.plugins"
_loaded = False


def load_plugins() -> None:
    """Run every installed plugin's registration once."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        ep.load()()
