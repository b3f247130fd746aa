"""The identification's check of a sensor's axes against each other (components.diagnosis.
noise_axes): an axis's slow term is named when its whole 3σ interval lies above the most the log
allows each other axis of the sensor — a present term's interval top, an absent one's upper
bound — and only then."""
import math
from types import SimpleNamespace

from components.diagnosis.noise_axes import unlike_axes
from components.model.noise import CHANNELS, UG, term_name

BI = "bias_instability"


def channels(acc_bi, acc_bounds):
    """Six channels: gyro without slow terms; acc axis k with the floor *acc_bi[k]* (None: absent,
    its upper bound acc_bounds[k]) and its interval acc_bounds[k] when present."""
    out = [SimpleNamespace(name=CHANNELS[k], present=["white"], slow={}, noise=SimpleNamespace(**{BI: 0.0}))
           for k in range(3)]
    intervals = {}
    for i, (v, b) in enumerate(zip(acc_bi, acc_bounds)):
        k = 3 + i
        if v is None:
            out.append(SimpleNamespace(name=CHANNELS[k], present=["white"], slow={BI: {"present": False, "upper": b}},
                                       noise=SimpleNamespace(**{BI: 0.0})))
        else:
            out.append(SimpleNamespace(name=CHANNELS[k], present=["white", BI], slow={BI: {"present": True}},
                                       noise=SimpleNamespace(**{BI: v})))
            intervals[term_name(k, BI)] = b
    return out, intervals


def test_an_axis_beyond_the_others_intervals_is_named_with_the_level_to_test_it_at():
    ch, iv = channels([20 * UG, 19 * UG, 102 * UG], [(15 * UG, 41 * UG), (14 * UG, 25 * UG), (58 * UG, 163 * UG)])
    lines = unlike_axes(ch, iv)
    assert len(lines) == 1 and lines[0].startswith("acc_z's bi 102 ug [58, 163]")
    assert "at most 41 ug" in lines[0] and "--noise identify --noise acc.noise.bi='41 ug'" in lines[0]


def test_an_absent_axis_counts_with_its_upper_bound():
    ch, iv = channels([None, 19 * UG, 102 * UG], [30 * UG, (14 * UG, 25 * UG), (58 * UG, 163 * UG)])
    assert len(unlike_axes(ch, iv)) == 1
    ch, iv = channels([None, 19 * UG, 102 * UG], [60 * UG, (14 * UG, 25 * UG), (58 * UG, 163 * UG)])
    assert unlike_axes(ch, iv) == []  # x may have as much as z shows: nothing tells them apart


def test_overlapping_or_unbounded_axes_are_not_named():
    ch, iv = channels([20 * UG, 19 * UG, 35 * UG], [(15 * UG, 41 * UG), (14 * UG, 25 * UG), (24 * UG, 50 * UG)])
    assert unlike_axes(ch, iv) == []
    ch, iv = channels([None, 19 * UG, 102 * UG], [math.nan, (14 * UG, 25 * UG), (58 * UG, 163 * UG)])
    assert unlike_axes(ch, iv) == []  # an axis with no bound at all: no comparison
