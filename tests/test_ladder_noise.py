"""Each rung of the ladder says the noise model its χ²/dof was taken under: `add` identifies the
noise again with the new effect in the model, so the rung before it was taken under another model
(on a MEMS log the same baseline read 0.991 in the ladder and 1.033 on the report's page, both
said to be 'whitened with the noise model')."""
from types import SimpleNamespace

import numpy as np

from components.diagnosis.ladder import ladder_entry, ladder_lines
from components.model.noise import ChannelNoise, NoiseModel, describe


def comparison(chi2_per_dof, noise):
    ch = {c: {"rms": 1.0, "noise_floor": 1.0} for c in ("gyro_x", "acc_x")}
    return SimpleNamespace(channels=ch, chi2_per_dof=chi2_per_dof,
                           noise_terms=describe(noise) if noise is not None and noise.coloured else None)


def model(acc_bi):
    chans = [ChannelNoise(white=1e-6)] * 3 + [ChannelNoise(white=1e-4, bias_instability=b) for b in acc_bi]
    return NoiseModel(tuple(chans), "test")


def test_rungs_under_different_noise_models_say_which():
    first, again = model([20e-5, 19e-5, 100e-5]), model([20e-5, 19e-5, 20e-5])
    ladder = [ladder_entry(comparison(0.991, first), ["acc.bias"]),
              ladder_entry(comparison(0.985, again), ["acc.bias", "acc.k2"], "+ acc.k2")]
    assert ladder[0]["noise"] == describe(first) != ladder[1]["noise"] == describe(again)
    lines = ladder_lines(ladder)
    assert any(describe(first) in line and line.strip().startswith("acc.bias:") for line in lines)
    assert any(describe(again) in line and line.strip().startswith("+ acc.k2:") for line in lines)


def test_rungs_under_one_noise_model_print_the_table_alone():
    same = model([20e-5] * 3)
    ladder = [ladder_entry(comparison(1.4, same), ["acc.bias"]), ladder_entry(comparison(1.0, same), ["acc.bias", "acc.k2"])]
    assert len(ladder_lines(ladder)) == 3
    white = [ladder_entry(comparison(1.4, None), ["acc.bias"])]
    assert white[0]["noise"] == "white noise" and np.isclose(white[0]["chi2_per_dof"], 1.4)
