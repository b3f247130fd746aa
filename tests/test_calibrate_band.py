"""calibrate says when χ²/dof is outside its 99.9 % band, as compare does."""
from __future__ import annotations

from components.cli import main


def test_calibrate_says_when_chi2_is_outside_its_band(conformance, tmp_path, capsys):
    """A noise model far noisier than the log (another IMU's noise file, a grade too coarse) gives
    χ²/dof far below 1 and σ far too wide; one far quieter, far above 1 and σ too small:
    calibrate says so (compare did; calibrate printed the number alone)."""
    log = str(conformance / "example")
    capsys.readouterr()
    assert main(["calibrate", log, "--out", str(tmp_path / "t.json"), "--noise", "tactical"]) == 0
    assert "below what a correct model gives" in capsys.readouterr().out
    assert main(["calibrate", log, "--out", str(tmp_path / "q.json"), "--noise", "gyro.noise.arw=1e-9 rad/sqrt(s)",
                 "--noise", "acc.noise.vrw=1e-9 m/s/sqrt(s)"]) == 0
    assert "above what a correct model gives" in capsys.readouterr().out
    assert main(["calibrate", log, "--out", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    assert "what a correct model gives" not in out, out
