"""simulate --check judges a run that injected slow noise under that noise (the scenario knows
it): under white noise its σ were white-noise σ and most accelerometer parameters read "OFF BY
MORE THAN 3 SIGMA" for no fault of the run (14 of 24 on a user's 14-minute log, up to 102 σ)."""
from __future__ import annotations

from pathlib import Path

from components.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_check_uses_the_injected_slow_noise(tmp_path, capsys):
    text = (ROOT / "examples" / "scenarios" / "six_position.toml").read_text()
    text = text.replace('"acc.noise.vrw" = "5 ug/sqrt(Hz)"', '"acc.noise.vrw" = "5 ug/sqrt(Hz)"\n'
                        '"acc.noise.bi" = "50 ug"\n"acc.noise.bi_tau" = 10.0\n"acc.noise.bi_tau_max" = 3600.0')
    assert "acc.noise.bi" in text
    scn = tmp_path / "bi.toml"
    scn.write_text(text)
    capsys.readouterr()
    assert main(["simulate", str(scn), "--out", str(tmp_path / "bi"), "--dwell", "10", "--check"]) == 0
    out = capsys.readouterr().out
    assert "noise the scenario's [imu.noise] (injected)" in out
    # 12 parameters with a σ each: more than one beyond 3σ has a chance of ~1e-4 when σ are right
    assert out.count("OFF BY MORE THAN 3 SIGMA") <= 1, out
