"""An effect the identified noise took for noise (components.diagnosis.taken_for_noise).

The FMUs' demo run without its K2, with the accelerometer bias instability of a navigation-grade
IMU and a temperature ramp of 0.05 K/s (15 K over the five minutes): with 20 ug/K on acc_z, the
identification on the baseline's residual takes the ramp for a random walk on acc_z, and under
that noise no effect is significant. The effect must then be named, by its likelihood ratio with
the slow terms free under both hypotheses; that ratio must be the profile one, recomputed here
from each channel's likelihood with and without the effect's columns (not from the design's
whitened χ²); and the same ramp with no coefficient must name nothing."""
from __future__ import annotations

import copy
import tomllib
from dataclasses import replace

import pytest

from components.cli.demo import SCENARIO
from components.diagnosis.candidate_design import CandidateDesign
from components.diagnosis.candidate_notes import verdict_lines
from components.diagnosis.diagnose import default_candidates, diagnose
from components.diagnosis.noise_choice import choose_noise
from components.diagnosis.noise_terms import ChannelRows, loglik, refit_terms
from components.diagnosis.ranking import rank
from components.diagnosis.taken_for_noise import identified_slow_terms, taken_for_noise, without_identified
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import DEFAULT_EFFECTS, EFFECTS, parameters_of
from components.model.noise import from_terms
from components.model.result import result_from_fit
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

BASELINE = list(DEFAULT_EFFECTS)
ALPHA = 0.01


def _ramp_log(coefficient: str | None, seed: int = 3):
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["imu"]["effects"].pop("acc.k2.z")
    if coefficient:
        d["imu"]["effects"]["acc.temp.z"] = coefficient
    d["imu"]["noise"] = {"gyro.noise.arw": "0.002 deg/sqrt(h)", "acc.noise.vrw": "10 ug/sqrt(Hz)",
                         "acc.noise.bi": "10 ug", "acc.noise.bi_tau": 10.0, "acc.noise.bi_tau_max": 3600.0}
    d["temperature"] = {"profile": [[0.0, 25.0], [400.0, 45.0]]}
    d["scenario"]["seed"] = seed
    data = LogData.from_log(run_scenario(scenario_from_dict(d, source="test_taken_for_noise"), progress=False).log)
    model = result_from_fit(calibrate(data, BASELINE), BASELINE, data)
    noise = choose_noise(["identify"], data, model, bootstrap=10)[0]  # (the bootstrap gives the fast terms σ only)
    return data, model, noise


@pytest.fixture(scope="module")
def ramp():
    return _ramp_log("20 ug/K")


def _design(data, model, noise):
    """The diagnosis's design and columns, built as diagnose builds them."""
    cands = default_candidates(list(model.effects))
    params = [p for p in dict.fromkeys(parameters_of(model.effects) + parameters_of(cands))
              if not p.startswith("table.")]
    design = CandidateDesign.on_table_log(data, model, params, 1.0, model.rest_angle_sigma(), noise, 1 << 20)
    available = {c: [p for p in EFFECTS[c].parameters if p in design.index] for c in cands}
    base = [p for p in parameters_of(model.effects) if p in design.index] + design.nuisance
    return design, base, {c: ps for c, ps in available.items() if ps}


def test_a_ramp_effect_the_identification_took_for_a_random_walk_is_named(ramp):
    data, model, noise = ramp
    assert "acc.noise.rrw" in identified_slow_terms(noise), noise.channels[5]
    d = diagnose(data, model, noise=noise)
    # under the identified noise the ordinary test does not see it ...
    assert not any(c.passes for c in d.ranking), [(c.effect, c.p_adjusted) for c in d.ranking[:3]]
    # ... and the test with the slow terms free names it (a ramp: temperature and time are one column)
    assert d.verdict in ("acc.temp", "acc.drift") and d.verdict_kind == "effect", d.found
    taken = d.steps[0]["taken_for_noise"]
    assert taken["likelihood_ratio"] > taken["critical"]
    assert taken["slow_terms_beside"]["acc.noise.rrw.z"] < 0.5 * taken["slow_terms"]["acc.noise.rrw.z"]
    # the verdict's line says what it was taken for, in the term's display unit: ug/sqrt(h) is
    # 1e-6 g0 per sqrt(3600 s)
    line = next(x for x in verdict_lines(d) if "taken it for noise" in x)
    per = 9.80665e-6 / 60.0
    said = f"acc_z's random walk {taken['slow_terms']['acc.noise.rrw.z'] / per:.3g} -> " \
           f"{taken['slow_terms_beside']['acc.noise.rrw.z'] / per:.3g} ug/sqrt(h)"
    assert said in line, line


def test_its_likelihood_ratio_is_the_profile_one_from_each_channels_likelihood(ramp):
    data, model, noise = ramp
    design, base, available = _design(data, model, noise)
    t = taken_for_noise(design, base, available, ALPHA, noise, rank)
    assert t is not None and t.effect in ("acc.temp", "acc.drift")
    terms = identified_slow_terms(noise)
    channels = [k for k in range(6) if any(term.startswith(("gyro.", "acc.")[k // 3]) for term in terms)]
    without_effect = ChannelRows(design, base)
    with_effect = ChannelRows(design, base + available[t.effect])
    best_without = max(loglik(without_effect, noise, channels),
                       loglik(without_effect, refit_terms(without_effect, noise, terms), channels))
    # the maximum over the same family with the effect: at least the model the selection goes on under
    lr = 2 * (loglik(with_effect, t.noise, channels) - best_without)
    assert t.likelihood_ratio == pytest.approx(lr, rel=1e-6, abs=1e-6)


def test_the_same_ramp_without_a_coefficient_names_nothing():
    data, model, noise = _ramp_log(None)
    assert identified_slow_terms(noise), "the check must have identified terms to try"
    d = diagnose(data, model, noise=noise)
    assert d.verdict is None, (d.found, d.steps)


def test_terms_given_by_hand_are_not_refitted():
    given = from_terms({"acc.noise.vrw": 1e-4, "acc.noise.bi": 1e-4, "acc.noise.rrw": 1e-5}, source="given by hand")
    assert identified_slow_terms(given) == []
    assert without_identified(given).channels == given.channels


def test_a_term_given_over_an_identified_model_is_given_and_the_rest_stay_identified():
    """`--noise identify --noise gyro.noise.bi=…`: the gyro floor is the user's (never refitted),
    the accelerometer's identified random walk is still the identification's."""
    identified = from_terms({"gyro.noise.arw": 1e-6, "gyro.noise.bi": 1e-7, "acc.noise.vrw": 1e-4,
                             "acc.noise.rrw.z": 1e-5}, source="identified on this log")
    identified = replace(identified, intervals={"gyro.noise.bi.x": (5e-8, 2e-7), "acc.noise.rrw.z": (5e-6, 2e-5)},
                         sigmas={"gyro.noise.bi.x": 3e-8, "acc.noise.rrw.z": 3e-6})
    assert identified_slow_terms(identified) == ["acc.noise.rrw", "gyro.noise.bi"]
    given = from_terms({"gyro.noise.bi": 2e-7}, identified, "given by hand")
    assert identified_slow_terms(given) == ["acc.noise.rrw"]
    assert given.intervals == {"acc.noise.rrw.z": (5e-6, 2e-5)} and given.sigmas == {"acc.noise.rrw.z": 3e-6}
    assert without_identified(given).channels[5].random_walk == 0 and without_identified(given).channels[0].bias_instability == 2e-7
