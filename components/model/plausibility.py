"""What cannot be true of an IMU, and what a log barely tells.

Two scales per effect of the vocabulary:

- the **plausible limit**: no real IMU of any grade — consumer MEMS included — has a parameter
  beyond it (a scale-factor error of 5 %, a misalignment of 3°, an accelerometer bias of 0.2 g).
  An estimate beyond it is not a calibration but a sign of a wrong input, and the pattern of
  such estimates names the likely cause: a scale factor of −100 % (a sign flipped, or a channel
  that does not respond), of 57.3 − 1 or 1/57.3 − 1 (degrees declared as radians or the
  reverse), of 1/dt − 1 or dt − 1 (rates declared as increments or the reverse), of 9.81 − 1 or
  1/9.81 − 1 (g declared as m/s² or the reverse); two axes swapped give scale factors of −100 %
  on both and misalignments of +1 rad between them.
- the **expected magnitude** of an IMU of the log's grade: the vocabulary's navigation-grade
  typical magnitude times the ratio of the log's white noise to a navigation-grade IMU's
  (gyro 0.002 °/√h, accelerometer 10 µg/√Hz), at least 1; a bias at least the noise model's bias
  instability (bias_floors). A σ more than ``WEAK`` times that is *weakly determined*: the log
  says little about it beyond what any such IMU has.
"""
from __future__ import annotations

import math

from components.model.effects import DEG_H, G0, UG, effect_of

# the largest magnitude a real IMU of any grade has, per effect (SI)
PLAUSIBLE = {
    "gyro.bias": 20 * math.pi / 180,          # 20 deg/s (consumer MEMS before calibration)
    "gyro.sf": 0.05, "gyro.sf_asym": 0.02, "gyro.mis": math.radians(3.0),
    "gyro.gsens": 1.0 * math.pi / 180 / G0,   # 1 deg/s/g
    "gyro.g2sens": 0.1 * math.pi / 180 / G0**2,
    "gyro.temp": 0.2 * math.pi / 180,         # 0.2 deg/s/K
    "gyro.sf_temp": 1e-3, "gyro.drift": 1.0 * math.pi / 180 / 3600,
    "acc.bias": 0.2 * G0, "acc.sf": 0.05, "acc.sf_asym": 0.02, "acc.mis": math.radians(3.0),
    "acc.k2": 0.02 / G0, "acc.k3": 0.01 / G0**2, "acc.cross": 0.02 / G0,
    "acc.lever": 0.2, "acc.temp": 5e-3 * G0, "acc.sf_temp": 1e-3, "acc.drift": 0.01 * G0 / 3600,
    "imu.time_offset": 0.1, "acc.time_offset": 0.05,
    "table.base_tilt": math.radians(2.0), "table.base_azimuth": math.radians(10.0), "table.nonorth": math.radians(0.5),
    "table.wobble": math.radians(0.5), "table.encoder": math.radians(0.5),
    "table.reversal": math.radians(0.5),
}
NAV_WHITE = {"gyro": 0.002 * DEG_H * 60, "acc": 10 * UG}   # per √s: 0.002 deg/√h, 10 ug/√Hz
WEAK = 10.0


def plausible_limit(parameter: str) -> float:
    """The largest magnitude of *parameter* any real IMU has (SI)."""
    e = effect_of(parameter)
    return PLAUSIBLE.get(e.name, 1e3 * e.typical)


def grade_factor(white_per_sqrt_s: dict[str, float]) -> dict[str, float]:
    """Per sensor, how many times noisier than navigation grade the log is (at least 1)."""
    return {s: max(1.0, float(v) / NAV_WHITE[s]) if v and math.isfinite(v) else 1.0
            for s, v in white_per_sqrt_s.items()}


def expected_magnitude(parameter: str, factor: dict[str, float], floor: dict[str, float] | None = None) -> float:
    """The typical magnitude of *parameter* for an IMU of the log's grade; at least *floor*'s
    value for its effect (e.g. bias_floors)."""
    e = effect_of(parameter)
    return max(e.typical * factor.get(e.target, 1.0), (floor or {}).get(e.name, 0.0))


def bias_floors(noise) -> dict[str, float]:
    """Per sensor, the least bias an IMU with the bias instability of *noise*
    (components.model.noise.NoiseModel; the median of its axes) has: its in-run instability. A
    bias from one turn-on to the next is several times that (navigation FOGs 0.003 against
    ~0.02 °/h, industrial MEMS 8 °/h against ~700), so a σ near it is a measurement of the
    bias, not a sign the log says little of it; white noise alone scales it too little (the ARW
    of a MEMS gyro is 150 times a navigation gyro's, its bias some thousands of times: every
    MEMS gyro bias was weakly determined at σ 7.6 °/h under its 8 °/h instability)."""
    if noise is None:
        return {}
    out = {}
    for sensor, axes in (("gyro", slice(0, 3)), ("acc", slice(3, 6))):
        levels = sorted(c.bias_instability for c in noise.channels[axes])
        if levels[1] > 0:
            out[f"{sensor}.bias"] = float(levels[1])
    return out


def weakly_determined(sigmas: dict[str, float], factor: dict[str, float],
                      floor: dict[str, float] | None = None) -> list[str]:
    """Parameters whose σ exceeds ``WEAK`` times the expected magnitude for the log's grade."""
    return [p for p, s in sigmas.items() if math.isfinite(s) and s > WEAK * expected_magnitude(p, factor, floor)]


def implausible(values: dict[str, float], sample_interval: float | None = None) -> dict[str, str]:
    """Estimates beyond the plausible limit, each with the likely cause its pattern shows."""
    out = {}
    for p, v in values.items():
        if not math.isfinite(v) or abs(v) > plausible_limit(p):
            out[p] = _cause(p, v, values, sample_interval)
    return out


def _near(v: float, target: float, rel: float = 0.05) -> bool:
    return abs(v - target) <= rel * abs(target)


def _cause(p: str, v: float, values: dict[str, float], dt: float | None) -> str:
    e = effect_of(p)
    sensor = e.target
    if e.name.endswith(".sf"):
        axis = p[-1]
        swapped = [q for q in values if q.startswith(f"{sensor}.mis.{axis}") and _near(values[q], 1.0, 0.1)]
        if _near(v, -1.0, 0.1) and swapped:
            other = swapped[0][-1]
            return (f"scale factor {100 * v:+.0f} % and {swapped[0]} = {values[swapped[0]]:+.2f} rad: axes {axis} "
                    f"and {other} look swapped in the mapping")
        if _near(v, -2.0, 0.1):
            return f"scale factor {100 * v:+.0f} %: the axis's sign looks flipped"
        ratio = 1.0 + v
        if dt:
            if _near(ratio, 1 / dt):
                return f"the output is 1/dt = {ratio:.4g} times the motion: rates declared as increments"
            if _near(ratio, dt, 0.1):
                return f"the output is dt = {ratio:.4g} times the motion: increments declared as rates"
        if _near(v, -1.0, 0.1):
            return (f"scale factor {100 * v:+.0f} %: the channel barely responds (a wrong column, or a sign "
                    "flip together with a swap)")
        # the unit mix-ups each sensor can have (a gyro knows no g, an accelerometer no degrees)
        mixups = ((180 / math.pi, "degrees declared as radians"), (math.pi / 180, "radians declared as degrees"),
                  (3600.0, "per hour declared as per second"), (1 / 3600.0, "per second declared as per hour")) \
            if sensor == "gyro" else ((G0, "g declared as m/s²"), (1 / G0, "m/s² declared as g"))
        for k, what in mixups:
            if _near(ratio, k):
                return f"the output is {ratio:.4g} times the motion: {what}"
        decade = round(math.log10(ratio)) if ratio > 0 else 0
        if decade and _near(ratio, 10.0 ** decade, 0.02):
            return (f"the output is {ratio:.4g} times the motion: a unit prefix or a pulse count weight off by "
                    f"10^{decade}")
        return f"scale factor {100 * v:+.3g} %: beyond any real IMU (check the units and the mapping)"
    if e.name.endswith(".mis") and abs(v) > 0.5:
        return f"misalignment of {math.degrees(v):+.0f}°: two axes look swapped or mixed in the mapping"
    if e.name == "acc.bias" and _near(abs(v), G0, 0.1):
        return "a bias of 1 g: gravity counted twice (an axis's sign or the 'up' convention)"
    return f"{v:+.4g} {e.unit} is beyond any real IMU ({plausible_limit(p):.3g} {e.unit}): check units and mapping"
