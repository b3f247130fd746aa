"""What motion makes each parameter of the vocabulary visible: the sentence a user reads when a
log does not determine it ("needs rests with x up and x down"). Axis letters are the IMU's
(body) axes; a parameter's indices fill the sentence."""
from __future__ import annotations

from components.model.effects import effect_of

# effect -> sentence; {i} the parameter's first index, {j} the second, {k} a third
_NEEDS = {
    "gyro.bias": "rests (any attitude) long enough to average the noise",
    "gyro.sf": "a rotation about {i}",
    "gyro.sf_asym": "rotations about {i} in both directions",
    "gyro.mis": "a rotation about {j}",
    "gyro.gsens": "rests with {j} up and with {j} down",
    "gyro.g2sens": "rests with the specific force along {j} and {k} at several angles",
    "gyro.temp": "a change of temperature",
    "gyro.sf_temp": "rotations about {i} at two temperatures",
    "gyro.drift": "rests spread over a long run",
    "acc.bias": "rests with {i} up and with {i} down",
    "acc.sf": "rests with {i} up and with {i} down",
    "acc.sf_asym": "rests with {i} up, {i} down and {i} horizontal",
    "acc.mis": "rests with {j} up and with {j} down",
    "acc.k2": "rests with {i} at ±1 g and at 0 g or ±45°",
    "acc.k3": "rests with {i} at ±1 g and at ±45°",
    "acc.cross": "rests with {i} and {j} both tilted (±45° between them)",
    "acc.lever": "fast rotations (centripetal acceleration at the accelerometers) and indexing starts and stops",
    "acc.temp": "a change of temperature",
    "acc.sf_temp": "rests with {i} up and down at two temperatures",
    "acc.drift": "rests spread over a long run",
    "imu.time_offset": "fast indexing moves (rate and specific force changing)",
    "acc.time_offset": "fast indexing moves (specific force changing)",
    "table.base_tilt": "indexing the outer axis through 0, 90, 180 and 270°",
    "table.base_azimuth": "gyros that sense the Earth's rate, rests at several outer angles",
    "table.nonorth": "rotations of each stage with the others at several angles",
    "table.wobble": "rotations of each stage through full turns, the IMU in two mountings",
    "table.encoder": "rests at many angles of each stage over a full turn",
    "table.reversal": "moves that turn back (each stage reaching rests from both sides)",
}


def needs(parameter: str) -> str:
    """The motion that would determine *parameter*."""
    e = effect_of(parameter)
    idx = parameter[len(e.name) + 1:] if len(parameter) > len(e.name) else ""
    letters = [c for c in idx.replace(".", "") if c in "xyz"]
    fill = {"i": letters[0] if letters else "the axis", "j": letters[1] if len(letters) > 1 else "another axis",
            "k": letters[2] if len(letters) > 2 else (letters[1] if len(letters) > 1 else "another axis")}
    return _NEEDS.get(e.name, "more varied motion").format(**fill)
