"""The noise block of a result or noise file: what is written is read back, the slow terms'
profile-likelihood intervals with their σ (units SI, as the file says)."""
import json

from components.model.noise import ChannelNoise, NoiseModel


def test_the_noise_block_keeps_values_sigmas_and_intervals_through_json():
    white = ChannelNoise(white=1e-6)
    floor = ChannelNoise(white=1e-4, bias_instability=1e-4, flicker_range=(12.5, None))
    m = NoiseModel((white, white, white, floor, floor, floor), "identified from this log's residual",
                   {"acc.noise.bi.z": 2e-5, "acc.noise.vrw.z": 1e-7},
                   {"acc.noise.bi.z": (6.1e-5, 1.9e-4)})
    d = json.loads(json.dumps(m.to_dict()))
    assert d["channels"]["acc_z"]["bias_instability"]["interval_3sigma"] == [6.1e-5, 1.9e-4]
    assert d["channels"]["acc_z"]["bias_instability"]["unit"] == "m/s2"
    back = NoiseModel.from_dict(d)
    assert back.channels == m.channels
    assert back.sigmas == m.sigmas
    assert back.intervals == m.intervals


def test_an_interval_the_log_does_not_bound_is_null_in_the_file():
    floor = ChannelNoise(white=1e-4, bias_instability=1e-4, flicker_range=(12.5, None))
    m = NoiseModel((floor,) * 6, "identified", {}, {"acc.noise.bi.x": (0.0, float("inf"))})
    text = json.dumps(m.to_dict(), allow_nan=False)  # strict JSON: no Infinity
    assert json.loads(text)["channels"]["acc_x"]["bias_instability"]["interval_3sigma"] == [None, None]
    assert NoiseModel.from_dict(json.loads(text)).intervals["acc.noise.bi.x"] == (0.0, float("inf"))
