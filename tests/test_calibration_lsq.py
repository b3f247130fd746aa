"""General least-squares calibration against the independent simulator's conformance vectors
(tests/data/conformance): truth recovery within the reported σ, a noise-free run giving zero
errors below the numerical floors, and apply/recalibrate consistency."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import ARCSEC, DEFAULT_EFFECTS, DEG_H, UG


def truth_values(examples: Path, name: str) -> dict:
    t = json.loads((examples / f"{name}.truth.json").read_text())["baseline"]
    Ag, Aa = np.array(t["gyro_matrix_minus_identity"]), np.array(t["acc_matrix_minus_identity"])
    out = {}
    for i, c in enumerate("xyz"):
        out[f"gyro.bias.{c}"] = t["gyro_bias_rad_s"][i]
        out[f"acc.bias.{c}"] = t["acc_bias_mps2"][i]
        out[f"gyro.sf.{c}"] = Ag[i, i]
        out[f"acc.sf.{c}"] = Aa[i, i]
        for j, d in enumerate("xyz"):
            if i != j:
                out[f"gyro.mis.{c}{d}"] = Ag[i, j]
                out[f"acc.mis.{c}{d}"] = Aa[i, j]
    return out


@pytest.fixture(scope="module")
def example_fit(conformance):
    data = LogData.from_log(read_log(conformance / "example"))
    return calibrate(data, list(DEFAULT_EFFECTS))


def test_example_truth_within_reported_sigma(example_fit, conformance):
    truth = truth_values(conformance, "example")
    z = np.array([(v - truth[p]) / s for p, v, s in zip(example_fit.parameters, example_fit.value,
                                                        example_fit.sigma)])
    assert len(z) == 24
    # every parameter within 4 σ, and the normalised errors look like unit Gaussians
    assert np.max(np.abs(z)) < 4.0, dict(zip(example_fit.parameters, z.round(2)))
    assert 0.5 < np.sqrt(np.mean(z**2)) < 1.6


def test_example_sigma_matches_the_noise_of_the_truth(example_fit, conformance):
    t = json.loads((conformance / "example.truth.json").read_text())["noise"]
    # per-sample white noise estimated from static data vs the simulator's stated values
    np.testing.assert_allclose(example_fit.sigma_gyro, t["sigma_dtheta_rad"], rtol=0.05)
    np.testing.assert_allclose(example_fit.sigma_acc, t["sigma_dv_mps"], rtol=0.05)
    dof = example_fit.dof
    assert abs(example_fit.chi2 / dof - 1) < 5 * math.sqrt(2 / dof)


def test_ideal_log_gives_zero_errors_below_numerical_floors(conformance):
    data = LogData.from_log(read_log(conformance / "ideal"))
    fit = calibrate(data, list(DEFAULT_EFFECTS) + ["acc.k2"])
    floors = {"gyro.bias": 1e-4 * DEG_H, "gyro.sf": 1e-8, "gyro.mis": 0.01 * ARCSEC,
              "acc.bias": 0.1 * UG, "acc.sf": 1e-8, "acc.mis": 0.01 * ARCSEC,
              "acc.k2": 0.1 * UG / 9.80665**2}
    for p, v in zip(fit.parameters, fit.value):
        floor = floors[p.rsplit(".", 1)[0]]
        assert abs(v) < floor, (p, v, floor)


def test_apply_then_recalibrate_gives_zero(tmp_path, example_fit, conformance):
    from components.logs.logfile import write_log
    from components.model.correct import correct_log
    from components.model.result import CalibrationResult, result_from_fit

    log = read_log(conformance / "example")
    data = LogData.from_log(log)
    res = result_from_fit(example_fit, list(DEFAULT_EFFECTS), data, log)
    res.save(tmp_path / "r.json")
    res = CalibrationResult.load(tmp_path / "r.json")
    write_log(tmp_path / "corr", correct_log(log, res))
    refit = calibrate(LogData.from_log(read_log(tmp_path / "corr")), list(DEFAULT_EFFECTS))
    # the corrected data hold no error left: every re-estimate is far inside its σ
    assert np.max(np.abs(refit.value / refit.sigma)) < 1e-3


def test_left_out_samples_leave_the_fit_and_the_rest_still_finds_the_truth(conformance, example_fit):
    """A time range over a move and a dwell, and a mask over part of a rest: the gyro move
    through the range is dropped (its integral is no longer the rest-to-rest rotation), the
    other rows keep their samples, and the estimate is still the truth within σ."""
    log = read_log(conformance / "example")
    seg = np.asarray(log.segment).astype(str)
    moves = np.nonzero(np.char.startswith(seg, "move"))[0]
    t0, t1 = float(log.time[moves[0]]), float(log.time[moves[0]] + 20.0)
    log.mask = np.ones(log.n, bool)
    log.mask[int(0.6 * log.n):int(0.6 * log.n) + 400] = False
    data = LogData.from_log(log, exclude=[[t0, t1]])
    assert data.left_out["mask = 0"] == 400 and data.left_out[f"t = {t0:g}-{t1:g} s (exclude)"] > 0
    fit = calibrate(data, list(DEFAULT_EFFECTS))
    rows = fit.rows
    used = np.zeros(log.n, bool)
    for a, b in zip(rows["start"], rows["stop"]):
        used[a:b] = True
    assert not used[~data.usable].any() and used[data.usable].mean() > 0.95
    assert len(rows["start"]) < len(example_fit.rows["start"])
    truth = truth_values(conformance, "example")
    z = np.array([(v - truth[p]) / s for p, v, s in zip(fit.parameters, fit.value, fit.sigma)])
    assert np.max(np.abs(z)) < 4.0


def test_a_channel_without_a_white_level_leaves_the_others_theirs(conformance):
    """A noise model whose gyro_x has no white level (a pulse channel whose counts hide it) still
    weighs gyro_y and gyro_z, and every accelerometer axis, by the levels it gives; only gyro_x's
    comes from the data. With one channel lacking a level, all three gyro axes took the data's:
    on counts that hide it that is next to nothing, and χ²/dof went from 0.78 to 1.14 with the
    σ too small. The levels given here are 3x the example's truth, so the data's cannot pass."""
    from components.model.noise import ChannelNoise, NoiseModel

    data = LogData.from_log(read_log(conformance / "example"))
    white = [0.0, 3 * 0.002 * DEG_H * 60, 3 * 0.002 * DEG_H * 60] + [3 * 10 * UG] * 3   # per √s
    noise = NoiseModel(tuple([ChannelNoise(quantization=1e-7)] + [ChannelNoise(white=w) for w in white[1:]]), "test")
    fit = calibrate(data, list(DEFAULT_EFFECTS), noise=noise)
    given = np.array(white) * math.sqrt(data.sample_interval)
    np.testing.assert_allclose(fit.sigma_gyro[1:], given[1:3], rtol=1e-6)   # (the mean interval against the nominal)
    np.testing.assert_allclose(fit.sigma_acc, given[3:], rtol=1e-6)
    # gyro_x's from the data: the example's 0.002 °/√h, not 3x it
    assert fit.sigma_gyro[0] == pytest.approx(given[1] / 3, rel=0.05)
