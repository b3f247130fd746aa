"""The axes of one sensor against each other: a triad's three gyros (or accelerometers) are one
make, one design, one electronics, and their slow noise is alike. One axis whose identified
floor or random walk lies beyond what the log allows the other two is more likely an effect on
that axis the model lacks, taken for noise — a g² term, a temperature coefficient on a ramp, a
drift — than noise: identified noise then soaks it up, χ²/dof is 1 and diagnose finds nothing
missing. The identification says so, naming the axis and how to test it. It compares the 3σ
intervals only, so it is silent where the other axes' bounds are loose. On a 36-minute MEMS log
with a K2 of 300 ug/g² on acc_z, the model without it: acc_z's floor 102 ug [58, 163] against at
most 41 on x and y, named. With 20 ug/K on acc_z under a 22 K ramp besides, and the K2 added:
the ramp's 430 ug went into acc_z's random walk, 176 ug/√h [94, 337], which the other axes'
bounds (< 158, < 237) do not rule out, and nothing is named."""
from __future__ import annotations

import math

from components.estimation.noise_likelihood import SLOW
from components.model.noise import TERMS, sensor_of, term_name


def _largest_allowed(channel, k: int, term: str, intervals: dict) -> float:
    """The most of *term* the log allows on channel *k*: the top of a present term's interval,
    an absent one's upper bound (NaN where neither is known)."""
    if term in channel.present:
        iv = intervals.get(term_name(k, term))
        return float(iv[1]) if iv else math.nan
    test = channel.slow.get(term)
    return float(test.get("upper", math.nan)) if isinstance(test, dict) else math.nan


def unlike_axes(channels: list, intervals: dict) -> list[str]:
    """One line per axis whose present slow term's whole interval (*intervals*: term name ->
    (low, high), the 3σ profile-likelihood interval) lies above the most the log allows each
    other axis of its sensor; *channels*: the six channels' identifications, gyro x y z then
    acc x y z (components.diagnosis.noise_id.ChannelIdentification)."""
    out = []
    for first in (0, 3):
        axes = range(first, first + 3)
        for term in SLOW:
            for k in axes:
                iv = intervals.get(term_name(k, term))
                if term not in channels[k].present or not iv:
                    continue
                others = [_largest_allowed(channels[j], j, term, intervals) for j in axes if j != k]
                if not all(math.isfinite(x) for x in others) or not iv[0] > max(others):
                    continue
                vname, _, unit, scale = TERMS[sensor_of(k)][term]
                value = getattr(channels[k].noise, term)
                out.append(
                    f"{channels[k].name}'s {vname.split('.', 2)[2]} {value / scale:.3g} {unit} [{iv[0] / scale:.3g}, "
                    f"{iv[1] / scale:.3g}] is beyond what this log allows the sensor's other axes (at most "
                    f"{max(others) / scale:.3g} {unit}): an effect on that axis the model lacks (a g² or "
                    "temperature term, a drift) can fit as noise, and identified noise then hides it; test it with "
                    f"every axis at the others' level (--noise identify --noise {vname}='{max(others) / scale:.3g} "
                    f"{unit}'), or run a schedule that tells the two apart (a heat and cool cycle for a temperature "
                    "term)")
    return out
