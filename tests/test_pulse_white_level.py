"""A pulse-count log whose static runs are short (30 s): past its quantization only a couple of
τ remain, so the white level is read with a wide σ, below three of it on some logs. Every
sensor has white noise: it is kept, not dropped. Dropped, the channel was weighed by its count
weight's quantization alone (one log in six: χ²/dof 5.0, gyro biases 5-13 σ off, a false
verdict). Checked on that log (this schedule, seed 6): χ²/dof within its 99 % band and every
white level present and within 3.5 of its σ of the truth."""
from __future__ import annotations

import math
import tomllib

from components.diagnosis.noise_choice import choose_noise
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import DEFAULT_EFFECTS
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

SCHEDULE = """
[schedule]
name = "twelve-and-turns"
description = "12 positions at headings 0/90, 30 s dwells, CW/CCW turns about z and x"
[parameters]
dwell = 30.0
rate = 20.0
[[steps]]
kind = "tumble"
attitudes_deg = [[0, 0, 0], [0, 180, 0], [0, 90, 0], [0, -90, 0], [0, 90, 90], [0, 90, -90],
                 [90, 0, 0], [90, 180, 0], [90, 90, 0], [90, -90, 0], [90, 90, 90], [90, 90, -90]]
dwell = "$dwell"
[[steps]]
kind = "index"
angles_deg = [0, 0, 0]
label = "z-up"
[[steps]]
kind = "dwell"
duration = 10.0
label = "z-up"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = "$rate"
turns = 1
label = "rotZ+"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = "-$rate"
turns = 1
label = "rotZ-"
[[steps]]
kind = "index"
angles_deg = [0, 90, 90]
label = "x-up"
[[steps]]
kind = "dwell"
duration = 10.0
label = "x-up"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = "$rate"
turns = 1
label = "rotX+"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = "-$rate"
turns = 1
label = "rotX-"
"""
ARW = 0.001 * math.pi / 180 / 60   # rad/√s
VRW = 5e-6 * 9.80665               # m/s²/√Hz


def _scenario(schedule_path, seed: int) -> dict:
    return tomllib.loads(f"""
[scenario]
name = "counts"
description = "navigation-grade white noise, pulse counts"
step = 0.005
controller_rate_hz = 10
seed = {seed}
[schedule]
path = "{schedule_path}"
[site]
latitude_deg = 39.9
height_m = 50.0
[turntable]
fmu = "builtin:turntable"
[imu]
fmu = "builtin:imu"
gyro_output = "counts"
acc_output = "counts"
count_weight = {{gyro = "1 urad", acc = "0.01 mm/s"}}
[imu.effects]
"gyro.bias.z" = "0.006 deg/h"
"gyro.sf.x" = "5 ppm"
"acc.bias.x" = "50 ug"
"acc.sf.z" = "35 ppm"
[imu.noise]
"gyro.noise.arw" = "0.001 deg/sqrt(h)"
"acc.noise.vrw" = "5 ug/sqrt(Hz)"
""")


def test_the_white_level_beside_coarse_counts_is_kept(tmp_path):
    path = tmp_path / "twelve.toml"
    path.write_text(SCHEDULE)
    run = run_scenario(scenario_from_dict(_scenario(path, 6), source="test"), progress=False)
    data = LogData.from_log(run.log)
    noise, said, ident = choose_noise(None, data)   # pulse counts: identified
    assert ident is not None and "identified" in said
    for k, truth in enumerate([ARW] * 3 + [VRW] * 3):
        c = ident.channels[k]
        assert "white" in c.present, (c.name, c.present, c.fast.notes)
        # within 3.5 of its σ: 0.3 % family-wise over the six channels
        assert abs(c.noise.white - truth) < 3.5 * c.sigma["white"], (c.name, c.noise.white, truth, c.sigma)
    fit = calibrate(data, list(DEFAULT_EFFECTS), noise=noise)
    assert abs(fit.chi2 / fit.dof - 1) < 2.58 * math.sqrt(2 / fit.dof), fit.chi2 / fit.dof


def test_counts_that_hide_the_white_level_are_refused_not_floored(tmp_path):
    """Counts of 10 µrad (2") and 1 mm/s on this white noise (2e-8 rad a sample): the sample
    differences are mostly 0 and no white level is identified. calibrate took a numerical floor
    (7e-20 rad) for it and gave σ off by up to 98 of themselves with exit 0; it refuses now,
    naming the channels and what to give, and the identification says the same where the noise
    is said. With the white level given (the truth, by hand), it calibrates."""
    import pytest

    from components.errors import EstimationError

    path = tmp_path / "twelve.toml"
    path.write_text(SCHEDULE)
    d = _scenario(path, 6)
    d["imu"]["count_weight"] = {"gyro": "10 urad", "acc": "1 mm/s"}
    data = LogData.from_log(run_scenario(scenario_from_dict(d, source="test"), progress=False).log)
    noise, said, ident = choose_noise(None, data)
    assert "no white-noise level found on" in said, said
    with pytest.raises(EstimationError, match=r"no white-noise level on .*gyro_x.*: its pulse counts are too coarse"):
        calibrate(data, list(DEFAULT_EFFECTS), noise=noise)
    given, _, _ = choose_noise(["gyro.noise.arw=0.001 deg/sqrt(h)", "acc.noise.vrw=5 ug/sqrt(Hz)",
                                "gyro.noise.q=10 urad", "acc.noise.q=1 mm/s"], data)
    fit = calibrate(data, list(DEFAULT_EFFECTS), noise=given)
    # (not its χ² band: counts this much coarser than the noise are a sawtooth, not the uniform
    # independent error the quantization term takes; χ²/dof 0.09 here, an open item of #14)
    assert fit.dof > 0 and all(math.isfinite(v) for v in fit.value)
