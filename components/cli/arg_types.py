"""Option types that refuse what no run can mean (a negative tolerance, a zero step) at the
command line, with argparse's one line and exit 2, instead of a run that fails or a verdict
about nothing."""
from __future__ import annotations

import argparse
import math


def positive(text: str) -> float:
    """A finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text}: expected a finite number > 0")
    return v
