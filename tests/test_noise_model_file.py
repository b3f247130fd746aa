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


def test_a_fixed_terms_sigma_is_null_not_nan():
    """A count weight's quantization is fixed, not estimated: its σ (NaN inside) is written as
    null, so the file is strict JSON that other tools parse."""
    q = ChannelNoise(white=1e-6, quantization=2.9e-7)
    m = NoiseModel((q,) * 6, "identified", {"gyro.noise.q.x": float("nan"), "gyro.noise.arw.x": 3e-9})
    text = json.dumps(m.to_dict(), allow_nan=False)
    d = json.loads(text)
    assert d["channels"]["gyro_x"]["quantization"]["sigma"] is None
    assert NoiseModel.from_dict(d).sigmas == {"gyro.noise.arw.x": 3e-9}


def _well_formed() -> dict:
    g, a = ChannelNoise(white=3e-7, bias_instability=2e-8), ChannelNoise(white=1e-4, random_walk=3e-7)
    return NoiseModel((g, g, g, a, a, a), "given").to_dict()


def test_a_malformed_noise_file_is_refused_naming_the_key(tmp_path, capsys):
    """A typed term, a missing or unknown channel, a negative, textual or non-SI value: one error
    naming the file and the key, exit 2 — never a channel silently left white."""
    import copy

    import pytest

    from components.cli import main
    from components.model.noise import NoiseModel

    def broken(edit):
        d = copy.deepcopy(_well_formed())
        edit(d["channels"])
        return d

    cases = {
        "channels.acc_x: unknown term 'whte'": broken(lambda c: c["acc_x"].update(whte=c["acc_x"].pop("white"))),
        "acc_x, acc_y, acc_z missing": broken(lambda c: [c.pop(k) for k in ("acc_x", "acc_y", "acc_z")]),
        "unknown channel 'gyro_q'": broken(lambda c: c.update(gyro_q={})),
        "channels.acc_y.white.value: -1": broken(lambda c: c["acc_y"]["white"].update(value=-1)),
        "channels.acc_y.white.value: 'abc'": broken(lambda c: c["acc_y"]["white"].update(value="abc")),
        "channels.gyro_z.white: unit 'deg/sqrt(h)'": broken(lambda c: c["gyro_z"]["white"].update(unit="deg/sqrt(h)")),
        "channels.gyro_y.gauss_markov[0].tau_s": broken(lambda c: c["gyro_y"].update(
            gauss_markov=[{"sigma": 1e-8, "tau_s": 0}])),
    }
    NoiseModel.from_dict(_well_formed())   # the unbroken file reads
    for k, (said, d) in enumerate(cases.items()):
        with pytest.raises(ValueError, match="expected|missing"):
            NoiseModel.from_dict(d)
        path = tmp_path / f"n{k}.json"
        path.write_text(json.dumps(d))
        assert main(["plan", "six_position", "--noise", str(path)]) == 2, said
        err = capsys.readouterr().err
        assert str(path) in err and said in err, (said, err)


def test_the_realised_model_falls_below_the_floor_under_its_range():
    """A flicker floor identified from 12 s up: its Gauss–Markov sum's Allan variance is the
    floor inside the range and falls away well below it (the noise table drew it flat, 22.7 ug
    against a measured 11.8 at 1.3 s), and equals the sum of the terms' own variances."""
    import numpy as np

    from components.model.flicker import FLICKER_AVAR, flicker_terms, gm_avar

    ch = ChannelNoise(bias_instability=1e-4, flicker_range=(12.0, 3600.0))
    tau = np.array([0.1, 1.0, 100.0, 300.0])
    got = ch.avar_realised(tau)
    want = sum(gm_avar(s, T, tau) for s, T in flicker_terms(1e-4, 12.0, 3600.0))
    np.testing.assert_allclose(got, want, rtol=1e-12)
    floor = FLICKER_AVAR * 1e-8
    assert got[0] < 0.05 * floor and abs(got[2] / floor - 1) < 0.1
    np.testing.assert_array_equal(ChannelNoise(white=1e-3).avar_realised(tau), ChannelNoise(white=1e-3).avar(tau))
