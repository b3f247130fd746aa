"""Every error calbench raises for a user's mistake or a run that cannot go on, in one leaf
module that any part of ``components`` may import (it imports nothing of the project).

Each class keeps the built-in parent it resembles (a bad file is a ``ValueError``, a run that
went wrong a ``RuntimeError``) and shares :class:`CalbenchError`, so the command line catches
one base class and prints one line instead of a traceback. Messages name what, where (file,
row, key, step) and what was expected.
"""
from __future__ import annotations


class CalbenchError(Exception):
    """Base of every error calbench reports to a user as one line."""


class UserError(CalbenchError, ValueError):
    """A mistake in what the user gave on the command line."""


class LogFormatError(CalbenchError, ValueError):
    """A measurement log breaks the ``calbench-log/1`` rules; the message names the file, the
    row or key, and what was expected."""


class MappingError(CalbenchError, ValueError):
    """An import mapping (``calbench import``) or the foreign file it describes is not what the
    mapping says: names the mapping file, the key, the input file, the column or row."""


class ResultFormatError(CalbenchError, ValueError):
    """A calibration result file (``calbench-result/1``) is not what the format says."""


class ScheduleError(CalbenchError, ValueError):
    """A schedule is wrong: the message names the file, step, key and what was expected."""


class ScenarioError(CalbenchError, ValueError):
    """A scenario file is wrong: names the file, the key and what was expected."""


class CampaignError(CalbenchError, ValueError):
    """A campaign file is wrong: names the file, the key and what was expected."""


class ScheduleFault(CalbenchError, RuntimeError):
    """The table did not do what the schedule asked (e.g. never settled): names the step."""


class SpillError(CalbenchError, OSError):
    """A long log's columns do not fit in the temporary directory they spill to: names the
    directory, the size and how to choose another."""


class EstimationError(CalbenchError, ValueError):
    """The data cannot give what was asked of an estimator (too few attitudes for the parameters,
    a segment description the data contradict): names the segment or parameter and what is
    needed."""


def whole_number_from_environment(name: str, default: int, least: int = 0) -> int:
    """The environment variable *name* as a whole number of at least *least*; *default* when it
    is unset or empty; anything else a UserError naming the variable and what it takes."""
    import os

    v = os.environ.get(name)
    if v is None or not v.strip():
        return default
    try:
        n = int(v.strip())
    except ValueError:
        n = None
    if n is None or n < least:
        raise UserError(f"environment variable {name}={v!r}: expected a whole number of at least {least}, "
                        f"written as digits (e.g. {max(least, 4)}), or unset for the default ({default})")
    return n
