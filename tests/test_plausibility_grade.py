"""How well a log determines a parameter against what an IMU of its grade has
(components.model.plausibility): a bias measured to a fraction of the sensor's own in-run bias
instability is determined, whatever its white noise says of the grade."""
import math

from components.model.effects import DEG_H
from components.model.noise import ChannelNoise, NoiseModel
from components.model.plausibility import bias_floors, grade_factor, weakly_determined

MEMS_ARW = 0.3 * DEG_H * 60  # 0.3 deg/sqrt(h) per sqrt(s)


def mems_noise(gyro_bi):
    gyro = [ChannelNoise(white=MEMS_ARW, bias_instability=b) for b in gyro_bi]
    return NoiseModel(tuple(gyro + [ChannelNoise(white=60e-6 * 9.80665)] * 3), "test")


def test_a_mems_gyro_bias_measured_below_its_bias_instability_is_not_weak():
    """The MEMS log of the user test: σ 7.6 deg/h under an 8 deg/h instability. By white noise
    alone (150 times navigation grade) the expected bias is 150 x the vocabulary's typical one,
    and 7.6 deg/h is above ten times that: named weak. The bias instability is a floor of the
    bias itself: a σ below it is a measurement."""
    sigma = {"gyro.bias.x": 7.6 * DEG_H}
    factor = grade_factor({"gyro": MEMS_ARW, "acc": 60e-6 * 9.80665})
    assert weakly_determined(sigma, factor) == ["gyro.bias.x"]
    assert weakly_determined(sigma, factor, bias_floors(mems_noise([8 * DEG_H] * 3))) == []
    # and a σ beyond ten times the floor is weak again
    assert weakly_determined({"gyro.bias.x": 90 * DEG_H}, factor, bias_floors(mems_noise([8 * DEG_H] * 3))) \
        == ["gyro.bias.x"]


def test_the_floor_is_the_median_axis_and_none_without_a_floor():
    assert math.isclose(bias_floors(mems_noise([1 * DEG_H, 8 * DEG_H, 50 * DEG_H]))["gyro.bias"], 8 * DEG_H)
    assert bias_floors(mems_noise([0.0, 0.0, 8 * DEG_H])) == {}  # one axis alone sets no floor for the triad
    assert bias_floors(None) == {}
