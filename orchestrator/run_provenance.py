"""The provenance of a run: the system, each unit's identity and what was set on it, the versions
of what ran and the host (recorded with every recording)."""
from __future__ import annotations

import platform
from pathlib import Path

import numpy as np

from orchestrator.units import sha256_file


def run_provenance(sim) -> dict:
    """What produced a run's recording: the system, each unit (file hash, what was set), versions."""
    import fmpy

    sysm = sim.system
    prov = {
        "system": {"name": sysm.name, "source": sysm.source, "step": sysm.step,
                   "start": sysm.start, "stop": sysm.stop, "algorithm": sysm.algorithm,
                   "order": sim.order, "record_every": sysm.record_every},
        "units": {n: {**u.provenance(),
                      # what was set: the role's settings (ours: its output kind) and the file's
                      "parameters": {**sim.role_settings.get(n, {}), **sim.system.unit(n).parameters},
                      "role_options": sim.system.unit(n).role_options,
                      "step_multiple": sim.system.unit(n).step_multiple}
                  for n, u in sim.units.items()},
        "versions": {"python": platform.python_version(), "numpy": np.__version__,
                     "fmpy": fmpy.__version__, "calbench": _calbench_version()},
        "host": platform.node(),
    }
    if sysm.source and Path(sysm.source).exists():
        prov["system"]["sha256"] = sha256_file(sysm.source)
    return prov


def _calbench_version() -> str:
    try:
        from importlib.metadata import version

        return version("calbench")
    except Exception:
        return "unknown"
