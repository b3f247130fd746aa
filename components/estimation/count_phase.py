"""How far a pulse output's input turned each rest block's count remainder, read from when its
counts ticked.

At rest a pulse channel's counts tick at a steady rate (Earth's rate or gravity's component, a
bias) that is seldom a whole number of counts per block; the remainder's harmonics then turn by
that fraction from block to block (components.model.count_remainder). The advance must be known
far better than one count per rest: the block sums alone give it only to a count over the rest,
but the samples give it to a sample's worth at each end. Between the rest's first tick and its
last, the input advanced by the counts in between to within one sample's advance at each end
(a tick says the phase crossed a whole count during that sample); so the rate is those counts
over those samples. A channel that counts several a sample is read the same way from what it
counts beyond the whole number every sample has. Moves, and the rests of a channel that is not a
pulse output, have no advance (NaN): the remainder after a move is taken as new. A rest goes on
through a gap of up to BRIDGED_GAP samples left out of the blocks (a lost packet: the sample after
it is left out, the lost one's counts gone with it; no move fits in so few samples), its rate read
over the whole: the blocks between two lost packets of a coarse count see a tick or two, and each
piece's own rate was off by much of a count (2" gyro counts with 0.2 % of the packets lost: the
gyros' block sums at χ²/dof 1.28 under their true noise). A longer gap ends the rest, each side
read at its own rate. Through a gap inside a rest the phase turns by the rest's rate over the
gap's time (the lost packet's with it, which the log has no row for), which block_noise carries
on; after a longer gap it is taken as new.

The advance so read is taken as exact. Its error is one rate over the rest, a phase error growing
with the lag, which no state of a linear filter carries; spread as a wander instead, it damped the
sawtooth toward independent remainders, which is the overconfident side (on simulated rests of 30
one-second blocks, 2" counts, navigation-grade noise, the rest rate's error over its σ had an RMS
of 1.22 with it, 1.09 without, 1.36 with independent remainders, at 0.013 counts a block — no
two ticks in a rest; at 3.02: 1.09, 1.04, 1.38). Taken as exact, the advance also sets part of
what the block sums show, so their χ² runs below its count where the counts tick (0.81-0.99 a
row on nine-block rests): a goodness of fit on the safe side.
"""
from __future__ import annotations

import numpy as np

from components.estimation.whitening import block_timing, channel_rows
from components.logs.spill import release

BRIDGED_GAP = 10  # samples: a rest's rate is read across a gap this short (the table cannot have moved)


def count_advance(data, rows: dict) -> dict:
    """{"advance": (R, 2)} for the rows (block sums) *rows* of *data*
    (components.estimation.log_data.LogData): each static block's input in the channel's unit
    as its rest's tick rate gives it, and the input through the gap before the row where the row
    goes on the rest of the one before it (0 where they meet); NaN for moves, for rows that start
    a rest (second column) and for channels that are not pulse outputs. {} when no channel is a
    pulse output."""
    weights = [w if w else None for w in data.count_weight]
    if not any(weights):
        return {}
    advance = np.full((len(rows["start"]), 2), np.nan)
    time = getattr(data, "time", None)
    interval = getattr(data, "sample_interval", None)  # (computed once; a long log's intervals are not made whole)
    for ch in range(6):
        w = weights[0 if ch < 3 else 1]
        if w is None:
            continue
        column = (data.gyro if ch < 3 else data.acc)
        idx = channel_rows(rows, ch)
        start, stop, still = rows["start"][idx], rows["stop"][idx], ~rows["moving"][idx]
        # rests: runs of static blocks, each starting at most BRIDGED_GAP samples after the last
        # one stopped
        gaps = block_timing(rows, idx, 1.0)[1]
        new = np.ones(len(idx), bool)
        new[1:] = ~still[:-1] | (gaps[1:] > BRIDGED_GAP)
        for h in np.flatnonzero(still & new):
            e = h
            while e + 1 < len(idx) and still[e + 1] and not new[e + 1]:
                e += 1
            a, b = int(start[h]), int(stop[e])
            counts = np.rint(np.asarray(column[a:b, ch % 3], float) / w)
            # the whole counts every sample gives (98 a sample of gravity on 1 mm/s counts) say
            # nothing of the phase: the ticks of what is left above them do
            whole = round(float(counts.sum()) / len(counts))  # (the nearest: most samples have it)
            extra = counts - whole
            ticks = np.flatnonzero(extra)
            if len(ticks) >= 2:
                f, last = int(ticks[0]), int(ticks[-1])
                rate = whole + float(extra[f + 1:last + 1].sum()) / (last - f)
            else:
                rate = float(counts.sum()) / (b - a)
            advance[idx[h:e + 1], 0] = rate * (stop[h:e + 1] - start[h:e + 1]) * w
            advance[idx[h + 1:e + 1], 1] = rate * _samples_between(time, interval, stop[h:e], start[h + 1:e + 1]) * w
            release(column)
    return {"advance": advance}


def _samples_between(time, interval: float | None, stops: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """How many sample intervals lie between each block's end (its last sample *stops* − 1) and
    the next one's start (its first sample *starts*): by the log's *time* and its median
    *interval* where it has them (a lost packet has no row, but its interval passed), else by the
    samples' indices."""
    gap = (starts - stops).astype(float)
    if time is None or len(time) < 2 or not len(stops):
        return gap
    if interval is None:
        interval = float(np.median(np.diff(np.asarray(time, float))))
    # from the end of sample stop - 1 to the start of sample start (the end of start - 1 on the grid)
    ends = np.asarray(time[starts], float) - np.asarray(time[stops - 1], float)
    return np.maximum(np.rint(ends / interval) - 1.0, gap)
