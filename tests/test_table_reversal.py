"""The table's reversal error (effects: table.reversal; components.model.motion) against its
definition, computed here from the geometry's kinematics at the true angles: at rest the plate is
r/2 past the reading on the side the stage last moved to, and a move's gyro integral is the
rotation between its two true rests."""
from __future__ import annotations

import math

import numpy as np
import pytest

from components.model.geometry import Stage, TableGeometry
from components.model.motion import approach_sides, ideal_increments, interpolate_angles

DT = 0.005
R = 5e-6  # rad (1 arcsec)


def _schedule():
    """Middle stage: rest at 0, to 90° (+), back to 0 (−), on to −30° (−), to 45° (+), each move a
    raised-cosine of 2 s, each rest 1 s; the outer and inner stages at 0."""
    rests = [0.0, 90.0, 0.0, -30.0, 45.0]
    pieces = [np.zeros(200)]
    for a, b in zip(rests[:-1], rests[1:]):
        u = np.arange(1, 401) / 400
        pieces.append(a + (b - a) * (1 - np.cos(np.pi * u)) / 2)
        pieces.append(np.full(200, b))
    middle = np.radians(np.concatenate(pieces))
    angles = np.zeros((len(middle), 3))
    angles[:, 1] = middle
    return DT * np.arange(1, len(middle) + 1), angles


GEO = TableGeometry((Stage("outer", (0, 0, 1)), Stage("middle", (1, 0, 0)), Stage("inner", (0, 0, 1))),
                    latitude=0.7)


@pytest.mark.parametrize("side0", [0, 1, -1])
def test_rests_and_moves_follow_the_definition(side0):
    time, angles = _schedule()
    start = np.array([0, side0, 0], np.int8)
    profile = interpolate_angles(time, angles, 3, DT, start)
    geo = GEO.with_stage("middle", reversal=R)
    gyro, acc = ideal_increments(profile, geo)
    gyro0, acc0 = ideal_increments(profile, GEO)
    # the sides, written out: the sign of the last change of the middle angle
    side = np.full(len(time), side0, float)
    for i in range(1, len(time)):
        d = np.sign(angles[i, 1] - angles[i - 1, 1])
        side[i] = d if d else side[i - 1]
    rest = profile.static
    true = angles[rest].copy()
    true[:, 1] += 0.5 * R * side[rest]
    _, omega, _, f = GEO.kinematics(true)
    np.testing.assert_allclose(gyro[rest], DT * omega, rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(acc[rest], DT * f, rtol=1e-12, atol=1e-15)
    # each move: the integral of the gyro changes by the rotation the side change makes about the
    # middle axis (plate x with the inner stage at 0); Earth rate over the move moves it by
    # ~ω_ie R T = 1e-9 of R
    edges = np.flatnonzero(np.diff(rest.astype(int)))
    moves = list(zip(edges[::2] + 1, edges[1::2] + 1))
    assert len(moves) == 4
    for a, b in moves:
        change = gyro[a:b].sum(axis=0) - gyro0[a:b].sum(axis=0)
        want = np.array([0.5 * R * (side[b - 1] - side[a - 1]), 0.0, 0.0])
        np.testing.assert_allclose(change, want, atol=1e-3 * R)
    # the reversals are where the sides say: 90 -> 0 and -30 -> 45 turn back, 0 -> -30 goes on;
    # 0 -> 90 turns back only when the stage last moved the other way
    turned = [side[b - 1] != side[a - 1] for a, b in moves]
    assert turned == [side0 != 1, True, False, True]


def test_sides_of_each_sample():
    angles = np.array([[0.0], [0.0], [1.0], [2.0], [2.0], [1.0], [1.0], [3.0]])
    assert approach_sides(angles, np.array([-1], np.int8))[:, 0].tolist() == [-1, -1, 1, 1, 1, -1, -1, 1]


def test_rests_at_one_angle_from_two_sides_are_two_attitudes():
    time, angles = _schedule()
    profile = interpolate_angles(time, angles, 3, DT, np.zeros(3, np.int8))
    zero = np.all(profile.attitudes == 0.0, axis=1)
    # 0 at the start (no side yet) and 0 reached from above
    assert sorted(profile.attitude_sides[zero, 1].tolist()) == [-1, 0]
    assert math.isclose(np.degrees(profile.attitudes[:, 1]).max(), 90.0)
