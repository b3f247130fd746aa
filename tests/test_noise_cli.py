"""calbench noise and --noise on the independent simulator's example log (white noise: ARW
0.002 deg/sqrt(h), VRW 10 ug/sqrt(Hz)): the identified model is white on every channel at the
injected levels; the noise file round-trips into calibrate; bad specifications are one clear
error."""
import json
import math

import pytest

from components.cli import main
from components.model.effects import DEG, UG

ARW, VRW = 0.002 * DEG / 60, 10 * UG


@pytest.fixture(scope="module")
def noise_file(conformance, tmp_path_factory):
    out = tmp_path_factory.mktemp("noise") / "noise.json"
    assert main(["noise", str(conformance / "example"), "--out", str(out), "--bootstrap", "10"]) == 0
    return out


def test_white_noise_log_is_identified_as_white_at_its_levels(noise_file):
    d = json.loads(noise_file.read_text())
    assert d["format"] == "calbench-noise/1"
    for name, ch in d["channels"].items():
        # only white noise found; no quantization, bias instability or random walk claimed
        assert set(ch) == {"white"}, (name, ch)
        truth = ARW if name.startswith("gyro") else VRW
        assert abs(ch["white"]["value"] - truth) < 3 * ch["white"]["sigma"] + 0.01 * truth, (name, ch)
    assert set(d["allan"]) == {"gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"}


def test_the_noise_file_holds_each_slow_terms_presence_test(noise_file):
    """White noise: on every channel the floor and the random walk are tested and absent — each
    ratio below its critical value (where a sensor's axes were tested together, their sum below
    theirs), at the 1 % family level: above the one-test 1 % point of χ²(1), 6.63 — with an upper
    bound in the term's SI unit that sits above 0 (a bound, not a value)."""
    from scipy import stats

    d = json.loads(noise_file.read_text())
    tests = d["presence_tests"]
    assert set(tests) == set(d["channels"])
    for name, by_term in tests.items():
        assert set(by_term) == {"bias_instability", "random_walk"}, name
        for term, t in by_term.items():
            assert t["present"] is False and term not in d["channels"][name], (name, term, t)
            assert t["critical"] > stats.chi2.isf(0.01, 1), (name, term, t)
            if "pooled_critical" in t:
                assert t["pooled_likelihood_ratio"] <= t["pooled_critical"], (name, term, t)
            else:
                assert t["likelihood_ratio"] <= t["critical"], (name, term, t)
            assert t["upper"] > 0 and t["unit"] == ("rad/s" if name.startswith("gyro") else "m/s2") + \
                ("" if term == "bias_instability" else "/sqrt(s)"), (name, term, t)


def test_noise_file_goes_into_calibrate_and_the_result(noise_file, conformance, tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["calibrate", str(conformance / "example"), "--out", str(out), "--noise", str(noise_file)]) == 0
    assert f"noise: from {noise_file}" in capsys.readouterr().out
    res = json.loads(out.read_text())
    # a white model: the rows are white-weighted, the result says which σ it used
    assert math.isclose(res["noise"]["gyro_arw_rad_per_sqrt_s"][0],
                        json.loads(noise_file.read_text())["channels"]["gyro_x"]["white"]["value"], rel_tol=1e-9)


@pytest.mark.parametrize("spec, message", [
    ("acc.noise.bogus=1", "unknown term 'acc.noise.bogus'"),
    ("acc.noise.bi=10 furlongs", "expected a number"),
    ("gyro.noise.arw=-1 deg/sqrt(h)", "expected a magnitude >= 0"),
    # (each of these was a traceback and exit 1)
    ("acc.noise.bi.w=10 ug", "expected <gyro|acc>.noise.<arw|vrw|q|bi|rrw|bi_tau_min|bi_tau_max>[.x|.y|.z]"),
    ("acc.noise.bi.x.y=10 ug", "expected <gyro|acc>.noise."),
    # a datasheet number without its unit: 0.005 rad/sqrt(s) is 17 deg/sqrt(h)
    ("gyro.noise.arw=0.005", "a number without its unit; write it with one, e.g. gyro.noise.arw='0.005 deg/sqrt(h)'"),
    ("nonsense", "expected identify, white, navigation, tactical"),
    ("missing.json", "cannot read a JSON noise file"),
])
def test_bad_noise_specification_is_one_clear_error(spec, message, conformance, tmp_path, capsys):
    rc = main(["calibrate", str(conformance / "example"), "--out", str(tmp_path / "r.json"), "--noise", spec])
    err = capsys.readouterr().err
    assert rc == 2 and message in err and "Traceback" not in err, err


@pytest.mark.parametrize("spec, message", [
    ("acc.noise.bogus=1", "unknown term 'acc.noise.bogus'"),
    ("acc.noise.bi.w=10 ug", "expected <gyro|acc>.noise.<arw|vrw|q|bi|rrw|bi_tau_min|bi_tau_max>[.x|.y|.z]"),
    ("gyro.noise.arw=0.005", "a number without its unit"),
    ("navigation", "expected a term given as NAME=VALUE"),
])
def test_a_bad_term_to_hold_is_one_clear_error(spec, message, conformance, tmp_path, capsys):
    """A term held in an identification (calbench noise --noise, or beside --noise identify) is
    checked as any term by hand: one error naming it, before the log is worked on."""
    for args in (["noise", str(conformance / "example"), "--noise", spec],
                 ["calibrate", str(conformance / "example"), "--out", str(tmp_path / "r.json"), "--noise", "identify",
                  "--noise", spec]):
        if args[0] == "calibrate" and "=" not in spec:
            continue   # (a grade beside identify is a whole model, applied in order)
        rc = main(args)
        err = capsys.readouterr().err
        assert rc == 2 and message in err and "Traceback" not in err, (args, err)


def test_the_flicker_range_given_by_hand(conformance, tmp_path, capsys):
    """bi_tau_min / bi_tau_max [s] bound the bias instability's flicker range by hand, as a noise
    file's flicker_range_s does (bi_tau_max crashed; a range could be given only in a file): the
    terms in SI against the units converted by hand, the model its noise file reads back as; a
    range upside down is one clear error."""
    from components.diagnosis.noise_choice import choose_noise
    from components.model.noise import NoiseModel

    given = ["gyro.noise.arw=0.005 deg/sqrt(h)", "gyro.noise.bi=0.1 deg/h", "gyro.noise.bi_tau_min=10",
             "gyro.noise.bi_tau_max=1 h", "acc.noise.vrw=20 ug/sqrt(Hz)", "acc.noise.bi=30 ug",
             "acc.noise.bi_tau_min=10 s", "acc.noise.bi_tau_max=3600"]
    by_hand, _, _ = choose_noise(given, None)
    assert all(ch.flicker_range == (10.0, 3600.0) for ch in by_hand.channels)
    doc = by_hand.to_dict()
    assert doc["channels"]["gyro_x"]["flicker_range_s"] == [10.0, 3600.0]
    back = NoiseModel.from_dict(doc)
    assert back.channels == by_hand.channels
    # the units converted independently: 0.1 deg/h, 0.005 deg/sqrt(h), 30 ug, 20 ug/sqrt(Hz)
    g, a = by_hand.channels[0], by_hand.channels[3]
    assert math.isclose(g.bias_instability, 0.1 * math.pi / 180 / 3600, rel_tol=1e-12)
    assert math.isclose(g.white, 0.005 * math.pi / 180 / 60, rel_tol=1e-12)
    assert math.isclose(a.bias_instability, 30e-6 * 9.80665, rel_tol=1e-12)
    assert math.isclose(a.white, 20e-6 * 9.80665, rel_tol=1e-12)
    rc = main(["calibrate", str(conformance / "example"), "--out", str(tmp_path / "r.json"),
               "--noise", "gyro.noise.bi_tau_min=100", "--noise", "gyro.noise.bi_tau_max=10"])
    err = capsys.readouterr().err
    assert rc == 2 and "expected 0 < bi_tau_min < bi_tau_max" in err and "Traceback" not in err, err


@pytest.mark.parametrize("samples", [10, 150])
def test_a_log_too_short_to_identify_noise_is_told_so(conformance, tmp_path, capsys, samples):
    """Ten samples at rest gave an identification with exit 0: a quantization 'present' on an
    increment output and white-noise bounds below the true level. Below MIN_STATIC_SAMPLES static
    samples the terms cannot be told apart, and noise says so, naming what to give instead."""
    import dataclasses

    from components.diagnosis.noise_id import MIN_STATIC_SAMPLES
    from components.logs.logfile import read_log, write_log

    assert samples < MIN_STATIC_SAMPLES
    log = read_log(conformance / "example")
    cut = dataclasses.replace(log, time=log.time[:samples], gimbal={k: v[:samples] for k, v in log.gimbal.items()},
                              gyro=log.gyro[:samples], acc=log.acc[:samples], temperature=log.temperature[:samples],
                              segment=log.segment[:samples], command={})
    write_log(tmp_path / "short", cut)
    rc = main(["noise", str(tmp_path / "short")])
    err = capsys.readouterr().err
    assert rc == 2 and "too few to tell the noise terms apart" in err and "--noise" in err, err
    assert "Traceback" not in err


def test_a_noise_free_log_gets_no_white_level_beyond_its_numbers_last_digits(conformance):
    """The noise-free conformance log: its static runs show no white level on most channels, and
    the whole log's block sums are then asked (test_pulse_white_level). They must not invent
    one: what they read is the scatter of the numbers' last digits, below 1e-12 of a sample's
    increment (about 7e-7 rad and 0.1 m/s), and the noise line says where it was read."""
    import numpy as np

    from components.diagnosis.noise_choice import choose_noise
    from components.estimation.log_data import LogData
    from components.logs.logfile import read_log
    from components.model.effects import DEFAULT_EFFECTS

    data = LogData.from_log(read_log(conformance / "ideal"))
    _, said, ident = choose_noise(["identify"], data, effects=list(DEFAULT_EFFECTS), bootstrap=0)
    hidden = [c for c in ident.channels if "white" not in c.fast.present]
    assert hidden, [c.fast.present for c in ident.channels]
    dt = data.sample_interval
    for c, inc in zip(ident.channels, np.hstack([data.gyro, data.acc]).T):
        assert c.noise.white * np.sqrt(dt) < 1e-12 * np.sqrt(np.mean(inc**2)), (c.name, c.noise.white)
    assert "from the whole log's block sums" in said, said
