"""Every exception the orchestrator raises, under one base :class:`OrchestratorError`.

A leaf module (it imports nothing from the project), so that any module can raise or catch
these without importing the module that happens to raise them, and a caller can tell the
orchestrator's reports apart from its own bugs with one ``except OrchestratorError``. A class
that subclassed a built-in exception before the base existed (``UnitParseError``: ``ValueError``)
still does.
"""
from __future__ import annotations


class OrchestratorError(Exception):
    """Base of every exception the orchestrator raises on purpose."""


class SystemError_(OrchestratorError):
    """A system description is wrong: the message names the file, the key and what was expected."""


class UnitError(OrchestratorError):
    """A unit failed: the message names the unit, what it was doing and its last log lines."""


class UnitParseError(OrchestratorError, ValueError):
    """A unit string (``rad/s2``) that :mod:`orchestrator.si` cannot read."""


class RoleError(OrchestratorError):
    """One or more units do not conform to their roles; the message lists every problem.

    ``checks`` holds every unit's :class:`~orchestrator.roles.RoleCheck`, the passing ones too."""

    def __init__(self, checks: list):
        self.checks = checks
        super().__init__("\n".join(c.report() for c in checks if not c.ok))


class AlgebraicLoopError(OrchestratorError):
    """Units whose outputs depend instantaneously on each other's outputs in a cycle."""


class SimulationFault(OrchestratorError):
    """A unit failed during the run. ``recording`` (a :class:`~orchestrator.recording.Recording`)
    holds everything recorded before it; ``saved`` is where it was written, if anywhere."""

    def __init__(self, message: str, recording, saved=None):
        self.recording = recording
        self.saved = saved
        rows = getattr(recording, "rows", None)
        # the initial values alone are no result: said so, not as "partial results"
        what = (f"the initial values only (no step completed) saved to {saved}" if rows is not None and rows <= 1
                else f"partial results saved to {saved}")
        super().__init__(message + (f"\n({what})" if saved else ""))


class NativeSpanFault(OrchestratorError):
    """A unit failed inside the native span loop. Internal: :meth:`Simulation.run
    <orchestrator.master.Simulation.run>` turns it into a :class:`SimulationFault`."""


class LibcosimUnsupported(OrchestratorError):
    """The system uses something libcosim cannot run; the message says what and where."""


class LibcosimError(OrchestratorError):
    """libcosim reported an error while running. ``recording`` holds the rows completed."""

    def __init__(self, message: str, recording=None):
        self.recording = recording
        super().__init__(message)
