"""Runs of a mask found a piece at a time (components.model.mask_runs) against the runs read off
the mask sample by sample, at piece boundaries of every kind: a run across a boundary, a run
ending or starting on one, a one-sample run, a mask all True or all False."""
import numpy as np
import pytest

from components.estimation.allan import static_runs
from components.model.approach import moving_runs
from components.model.mask_runs import runs


def runs_by_hand(mask, value=True):
    out, start = [], None
    for i, m in enumerate(mask):
        if bool(m) == value and start is None:
            start = i
        elif bool(m) != value and start is not None:
            out.append((start, i))
            start = None
    if start is not None:
        out.append((start, len(mask)))
    return out


@pytest.mark.parametrize("piece", [1, 2, 3, 7, 8, 1000])
@pytest.mark.parametrize("value", [True, False])
def test_runs_equal_the_sample_by_sample_runs(piece, value):
    rng = np.random.default_rng(3)
    masks = [np.zeros(0, bool), np.ones(9, bool), np.zeros(9, bool), np.array([True]), np.array([False]),
             np.array([1, 0, 1, 1, 0, 0, 0, 1], bool)]
    # long rests with short moves, and a dithering stretch: runs of one sample to hundreds
    masks += [rng.random(300) < p for p in (0.05, 0.5, 0.95)]
    masks.append(np.repeat(rng.random(40) < 0.5, rng.integers(1, 30, 40)))
    for mask in masks:
        got = list(zip(*(x.tolist() for x in runs(mask, value, piece=piece))))
        assert got == runs_by_hand(mask, value), (mask.astype(int), piece)


def test_the_callers_keep_their_meaning():
    static = np.array([1, 1, 0, 0, 1, 1, 1, 0, 1], bool)
    assert [(int(a), int(b)) for a, b in moving_runs(static)] == [(2, 4), (7, 8)]
    assert static_runs(static, 2) == [(0, 2), (4, 7)]
    assert static_runs(static, 3) == [(4, 7)]
