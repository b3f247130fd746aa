""""Where the model fails" is a statistical statement (components.diagnosis.misfit): a segment,
condition or channel is flagged only when its χ² survives the Holm correction over every cell
looked at. Checked against pure-noise draws (the family-wise false-alarm rate is at most α), on
the spec's example log with its true model (bias, scale factor, misalignment: nothing flagged),
on simulated logs with every effect modelled (nothing flagged, over seeds) and with one effect
missing (flagged: the test can fail), and the demo's run before and after adding its effect."""
from __future__ import annotations

import copy
import dataclasses
import tomllib

import numpy as np
import pytest

from components.cli.demo import SCENARIO
from components.diagnosis.compare import compare
from components.diagnosis.misfit import ALPHA, holm, misfits
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS
from components.model.result import result_from_fit
from components.simulation.multi_imu import Variant, run_variants
from components.simulation.scenario import scenario_from_dict

BASELINE = list(DEFAULT_EFFECTS)
NULL_SEEDS = 6


def _rows(n_segments: int, blocks: int, rng):
    """Block rows of pure noise: n_segments × 6 channels × blocks."""
    seg = np.repeat(np.arange(n_segments), 6 * blocks).astype(str)
    ch = np.tile(np.repeat(np.arange(6), blocks), n_segments)
    return {"z": rng.standard_normal(seg.size), "channel": ch}, seg


def test_holm_matches_its_definition():
    p = np.array([0.01, 0.04, 0.03, 0.005])
    # sorted 0.005, 0.01, 0.03, 0.04 -> 4*0.005, 3*0.01, 2*0.03, 1*0.04, running max
    assert np.allclose(holm(p), [0.03, 0.06, 0.06, 0.02])


def test_pure_noise_flags_a_cell_at_most_alpha_of_the_time():
    rng = np.random.default_rng(5)
    draws = 400
    any_flag = 0
    largest = []
    for _ in range(draws):
        rows, seg = _rows(90, 4, rng)
        m = misfits(rows, seg, {})
        any_flag += bool(m.flagged("segment"))
        largest.append(max(c.ratio for c in m.cells["segment"]))
    # the naive "largest RMS" is far above 1 on pure noise: what the old wording called failure
    assert np.median(largest) > 1.8
    # family-wise error ≤ α: with 400 draws, P(Binomial(400, 0.01) > 10) < 0.003
    assert any_flag <= 10, any_flag


def test_a_shifted_cell_is_flagged_and_named():
    rng = np.random.default_rng(6)
    rows, seg = _rows(90, 4, rng)
    bad = (seg == "17") & (rows["channel"] == 4)
    rows["z"][bad] += 3.0  # a systematic error of 3 σ per block in one segment × channel
    m = misfits(rows, seg, {})
    assert [(c.name, c.channel) for c in m.flagged("segment")] == [("17", "acc_y")]
    assert "no segment × channel misfits" not in " ".join(m.lines())


def _comparison(log, effects):
    data = LogData.from_log(log)
    fit = calibrate(data, effects)
    model = result_from_fit(fit, effects, data, log)
    return compare(data, model, fitted_parameters=len(model.values))


def _flagged(comp) -> dict:
    return {f: [(c.name, c.channel) for c in comp.misfits.flagged(f)] for f in comp.misfits.cells}


def test_spec_example_with_its_true_model_flags_nothing(conformance):
    comp = _comparison(read_log(conformance / "example"), BASELINE)
    assert comp.misfits.looked_at("segment") > 50
    assert all(not v for v in _flagged(comp).values()), _flagged(comp)


def test_the_same_log_with_a_model_missing_effects_flags(conformance):
    comp = _comparison(read_log(conformance / "example"), ["gyro.bias", "acc.bias"])
    flagged = _flagged(comp)
    assert flagged["segment"] and flagged["channel"]


@pytest.fixture(scope="module")
def simulated():
    """The demo's scenario (2 s dwells): its baseline errors and K2 on z, one table run; IMUs with
    different noise seeds."""
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    k2 = d["imu"]["effects"].pop("acc.k2.z")
    d["schedule"]["overrides"]["dwell"] = 2.0
    sc = scenario_from_dict(d, source="test_where_it_fails")
    from components.model.quantities import effect_value

    variants = [Variant(f"null:{s}", seed=700 + s) for s in range(NULL_SEEDS)]
    variants.append(Variant("k2", effects={"acc.k2.z": effect_value("acc.k2.z", k2, "test")}, seed=11))
    return {n: lg for n, (lg, _) in run_variants(sc, variants).items()}


def test_every_effect_modelled_flags_nothing_over_seeds(simulated):
    families_with_a_flag = 0
    families = 0
    for s in range(NULL_SEEDS):
        flagged = _flagged(_comparison(simulated[f"null:{s}"], BASELINE))
        families += len(flagged)
        families_with_a_flag += sum(bool(v) for v in flagged.values())
    # each family has a false-alarm rate ≤ α = 0.01; over 18 families P(≥ 2) < 0.015
    assert ALPHA == 0.01
    assert families_with_a_flag <= 1, families_with_a_flag


def test_demo_run_flags_the_missing_effect_and_nothing_after_add(simulated):
    before = _flagged(_comparison(simulated["k2"], BASELINE))
    # K2 on z shows where z carries ±1 g: the z accelerometer channel must be named
    assert ("acc_z", "acc_z") in before["channel"], before
    assert any(ch == "acc_z" for _, ch in before["segment"]), before
    after = _flagged(_comparison(simulated["k2"], BASELINE + ["acc.k2"]))
    assert all(not v for v in after.values()), after


def test_a_constant_temperature_has_no_temperature_conditions(conformance):
    """Thirds of a temperature that never changes are no conditions (every row fell in 'low', which
    a misfit was then said to belong to); a ramp has all three, a third of the rows each."""
    log = read_log(conformance / "example")
    flat = dataclasses.replace(log, temperature=np.full(log.n, 25.0))
    assert not [k for k in _comparison(flat, BASELINE).conditions if k.startswith("temperature")]
    ramp = dataclasses.replace(log, temperature=np.linspace(20.0, 40.0, log.n))
    got = _comparison(ramp, BASELINE).conditions
    assert {"temperature low", "temperature mid", "temperature high"} <= set(got)


def test_a_noise_free_log_is_said_to_be_noise_free(conformance):
    """The spec's ideal vector carries no noise (its residual's differences are rounding): every
    channel is marked noise-free, so its χ² is not read as a misfit; the example, with noise,
    has none marked."""
    ideal = _comparison(read_log(conformance / "ideal"), list(DEFAULT_EFFECTS))
    assert all(v["noise_free"] for v in ideal.channels.values()), ideal.channels
    example = _comparison(read_log(conformance / "example"), BASELINE)
    assert not any(v["noise_free"] for v in example.channels.values())
