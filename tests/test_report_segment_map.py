"""The report's segment × channel heat map on a log of many segments (an 8-hour log has 768): it
shows at most MAP_ROWS of them — every flagged one, then those farthest from noise on a log
scale — in the log's order, and its image stays the size of that many rows (a map of every
segment was a 29 000-pixel image and most of the report's peak memory)."""
from __future__ import annotations

import math
import re
from types import SimpleNamespace

import numpy as np

from components.diagnosis.report_plots import MAP_ROWS, map_segments, segment_map

RNG = np.random.default_rng(7)


def _per_segment(n: int) -> dict:
    out = {}
    for i in range(n):
        v = np.exp(RNG.normal(0.0, 0.3, 6)).tolist()
        if i % 7 == 0:
            v[i % 6] = None  # a channel without blocks in the segment
        out[f"r{i // 64:02d}-pos{i % 64:02d}"] = v
    return out


def test_few_segments_are_all_shown_in_order():
    per = _per_segment(MAP_ROWS)
    assert map_segments(per) == list(per)


def test_many_segments_show_the_flagged_then_the_farthest_from_noise_in_log_order():
    per = _per_segment(500)
    names = list(per)
    flagged = [names[3], names[250], names[499]]
    for s in flagged:
        per[s] = [1.0] * 6  # flagged, though at noise on the scale (a Holm-significant cell need not be the largest)
    shown = map_segments(per, flagged)
    assert len(shown) == MAP_ROWS and set(flagged) <= set(shown)
    assert shown == [s for s in names if s in set(shown)]  # the log's order

    def far(s):
        return max(abs(math.log(x)) for x in per[s] if x is not None)
    rest = sorted((s for s in names if s not in flagged), key=far, reverse=True)
    assert set(shown) - set(flagged) == set(rest[:MAP_ROWS - len(flagged)])


def _height(svg: str) -> float:
    return float(re.search(r'<svg[^>]*height="([\d.]+)pt"', svg).group(1))


def test_the_maps_size_is_bounded_by_the_rows_it_shows():
    small = SimpleNamespace(per_segment=_per_segment(MAP_ROWS), misfits=None)
    large = SimpleNamespace(per_segment=_per_segment(768), misfits=None)
    svg = segment_map(large, "model")
    assert "farthest from noise" in svg
    assert _height(svg) <= 1.05 * _height(segment_map(small, "model"))
