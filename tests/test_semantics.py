"""The unit checks (components.estimation.semantics): the gyro's rotation over what the table
angles' chords give during the moves, the accelerometers' gravity at rest."""
import dataclasses

import numpy as np
import pytest

from components.estimation import semantics
from components.estimation.log_data import LogData
from components.logs.logfile import read_log


def _ratio(data):
    ideal, moving = semantics._ideal_gyro_moving(data, data.usable)
    upto = len(moving)
    assert np.array_equal(moving, (~data.static & data.usable)[:upto])  # the mask it made a window at a time
    measured = semantics._norms(data.gyro[:upto], moving)
    expected = np.linalg.norm(ideal, axis=1)
    assert len(ideal) == np.count_nonzero(moving)
    turning = expected > 0.1 * np.median(expected)
    return np.median(measured[turning] / expected[turning]), len(ideal)


@pytest.mark.parametrize("enough", [50_000, 700])
def test_the_gyros_turn_as_the_angles_say(conformance, monkeypatch, enough):
    """On the independent simulator's log the gyros turn 1.000 × what the angles' chords give
    (scale factors of a few hundred ppm), from all its moving samples or the first few hundred;
    with the angles in degrees declared as radians, 180/π."""
    monkeypatch.setattr(semantics, "ENOUGH_MOVING", enough)
    log = read_log(conformance / "example")
    data = LogData.from_log(log)
    ratio, picked = _ratio(data)
    assert ratio == pytest.approx(1.0, abs=2e-3)
    assert picked == min(enough, np.count_nonzero(~data.static & data.usable))
    bad = dataclasses.replace(log, gimbal={k: np.degrees(v) for k, v in log.gimbal.items()})
    ratio_bad, _ = _ratio(LogData.from_log(bad))
    assert ratio_bad == pytest.approx(np.pi / 180, rel=2e-3)


def test_dithering_encoder_at_rest_is_not_a_move_of_the_gyros(conformance):
    """An angle readout flickering by one count at rest makes a 'move' of every other sample;
    the check still reads the real moves (the flicker's expected rotation is below a tenth of
    the median and left out)."""
    log = read_log(conformance / "example")
    a = dict(log.gimbal)
    name = next(iter(a))
    angle = a[name].copy()
    rest = np.concatenate([[False], angle[1:] == angle[:-1]])
    flick = rest & (np.arange(len(angle)) % 2 == 0)
    angle[flick] += 2 * np.pi / 2**24  # one count of a 24-bit encoder
    ratio, _ = _ratio(LogData.from_log(dataclasses.replace(log, gimbal={**a, name: angle})))
    assert ratio == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("enough", [1 << 20, 1 << 16, 500])
def test_the_accelerometers_read_gravity_from_a_spread_of_the_rests(conformance, monkeypatch, enough):
    """The accelerometers' check reads g at rest from every rest sample, or from a stride of
    them over the whole log; increments declared as specific force are found either way, and
    the right declaration says nothing."""
    monkeypatch.setattr(semantics, "ENOUGH_STATIC", enough)
    log = read_log(conformance / "example")
    assert semantics.check_semantics(LogData.from_log(log), log) == []
    bad = dataclasses.replace(log, acc_output="specific_force")
    found = semantics.check_semantics(LogData.from_log(bad), bad)
    assert len(found) == 1 and "increments declared as specific force" in found[0]
    ratio = float(found[0].split("declared (specific_force), ")[1].split(" ×")[0])
    assert ratio == pytest.approx(log.dt, rel=2e-3)
