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
    ("gyro.noise.arw=-1", "expected a magnitude >= 0"),
    ("nonsense", "expected identify, white, navigation, tactical"),
    ("missing.json", "cannot read a JSON noise file"),
])
def test_bad_noise_specification_is_one_clear_error(spec, message, conformance, tmp_path, capsys):
    rc = main(["calibrate", str(conformance / "example"), "--out", str(tmp_path / "r.json"), "--noise", spec])
    err = capsys.readouterr().err
    assert rc == 2 and message in err and "Traceback" not in err, err
