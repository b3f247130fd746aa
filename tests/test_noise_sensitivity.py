"""σ with the unseen slow noise terms at their bounds (components.estimation.noise_sensitivity).

- Generalised least squares: more noise covariance can only widen the estimator's covariance
  (Loewner order), so no σ at the bounds is below the σ reported.
- On a short log with the issue's navigation-grade noise, whose gyro floor and random walks the
  likelihood cannot see: the σ under the true noise lies below the σ at the bounds for every
  parameter (the truth is below each absent term's bound), while the reported σ of the gyro
  biases is below it — the case the bound is for."""
from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from components.cli.demo import SCENARIO
from components.diagnosis.noise_id import identify_noise
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.estimation.noise_sensitivity import at_upper_bounds, sensitivity, sigma_under
from components.model.effects import DEFAULT_EFFECTS
from components.model.noise import from_fmu_parameters
from components.model.quantities import noise_value
from components.model.result import result_from_fit
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

NOISE = {"gyro.noise.arw": "0.002 deg/sqrt(h)", "gyro.noise.bi": "0.003 deg/h",
         "gyro.noise.bi_tau": 10.0, "gyro.noise.bi_tau_max": 3600.0, "gyro.noise.rrw": "0.0003 deg/h/sqrt(h)",
         "acc.noise.vrw": "10 ug/sqrt(Hz)", "acc.noise.bi": "10 ug", "acc.noise.bi_tau": 10.0,
         "acc.noise.bi_tau_max": 3600.0, "acc.noise.rrw": "1 ug/sqrt(h)"}
EFFECTS = list(DEFAULT_EFFECTS) + ["acc.k2"]


@pytest.fixture(scope="module")
def identified():
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["imu"]["noise"] = dict(NOISE)
    d["scenario"]["seed"] = 41
    data = LogData.from_log(run_scenario(scenario_from_dict(d, source="test_noise_sensitivity"), progress=False).log)
    white = result_from_fit(calibrate(data, EFFECTS), EFFECTS, data)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CALBENCH_WORKERS", "2")  # the channels on two forked processes
        ident = identify_noise(data, white, bootstrap=10)
    fit = calibrate(data, EFFECTS, noise=ident.model)
    return data, ident, fit, white


def test_the_channels_on_two_processes_give_the_same_bits(identified, monkeypatch):
    """The six channels' identification on forked processes is what one process gives, term by
    term, σ and likelihood-stage report included."""
    data, ident, _, white = identified
    monkeypatch.setenv("CALBENCH_WORKERS", "1")
    alone = identify_noise(data, white, bootstrap=10)
    assert alone.model.channels == ident.model.channels
    for a, b in zip(alone.channels, ident.channels):
        assert repr(a.sigma) == repr(b.sigma) and a.present == b.present  # (NaN: an unbounded σ)
        assert repr(a.slow) == repr(b.slow)
        assert np.array_equal(a.fast.allan.avar, b.fast.allan.avar)


def test_sigma_at_the_bounds_is_never_below_the_reported(identified):
    data, ident, fit, _ = identified
    span = float(data.time[-1] - data.start_time)
    sens = sensitivity(fit, ident, span)
    assert sens is not None and sens["terms_at_upper_bound"]
    ratios = np.array(list(sens["ratio"].values()))
    assert np.all(ratios >= 1 - 1e-9), sens["ratio"]


def test_the_true_sigma_lies_below_the_bound(identified):
    data, ident, fit, _ = identified
    span = float(data.time[-1] - data.start_time)
    noise, added = at_upper_bounds(ident)
    assert any(t.startswith("gyro") and "bias_instability" in t for t in added), added
    truth = from_fmu_parameters({k: noise_value(k, v, "test") for k, v in NOISE.items()})
    true_sigma = sigma_under(fit, truth, span)
    bounded = sigma_under(fit, noise, span)
    assert np.all(true_sigma <= bounded), dict(zip(fit.parameters, true_sigma / bounded))
    # what the bound is for: the identified model's σ of the gyro biases is below the true one
    gb = [fit.parameters.index(f"gyro.bias.{a}") for a in "xyz"]
    assert np.all(fit.sigma[gb] < true_sigma[gb]), (fit.sigma[gb], true_sigma[gb])


def test_a_white_level_read_at_the_one_sigma_limit_goes_in_at_its_three_sigma_limit():
    """A pulse channel's white level the block sums bound only from above has no σ and the
    interval [0, three-σ limit]: at the bounds it takes that limit; a white level measured with
    a σ stays as it is, and so does one whose limit lies below it (nothing to widen)."""
    from components.diagnosis.noise_id import ChannelIdentification, NoiseIdentification
    from components.model.noise import CHANNELS, ChannelNoise, NoiseModel

    levels = [1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4]
    chans = tuple(ChannelNoise(white=w, quantization=w) for w in levels)
    intervals = {"acc.noise.vrw.y": (0.0, 3e-4), "acc.noise.vrw.z": (0.0, 3e-4), "acc.noise.vrw.x": (0.0, 5e-5)}
    sigma = [{"white": 1e-8}] * 3 + [{"white": float("nan")}, {"white": float("nan")}, {"white": 1e-6}]
    ident = NoiseIdentification(NoiseModel(chans, "identified", {}, intervals), [
        ChannelIdentification(CHANNELS[k], None, {}, chans[k], sigma[k], ["quantization", "white"]) for k in range(6)])
    noise, added = at_upper_bounds(ident)
    assert added == ["acc_y white"]
    assert [c.white for c in noise.channels] == levels[:4] + [3e-4, 1e-4]
    assert [c.quantization for c in noise.channels] == levels
