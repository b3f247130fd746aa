"""Mistakes with the co-simulation commands get one line naming the option, file or key and exit
2, before anything runs, never a traceback nor a verdict about nothing (a user-style run found
each of these: a verify PASS with no step compared, tracebacks for a zero step, a directory, a
misspelt builtin FMU, an FMU without a binary for this machine)."""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

from components.cli import main
from fmus.build import fmu_path

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT / "examples" / "libcosim_pair.toml"


def _err(capsys, argv) -> str:
    """stderr of a command that must exit 2 (argparse's SystemExit or the command's own)."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    assert code == 2, argv
    return capsys.readouterr().err


@pytest.mark.parametrize("argv, said", [
    (["verify", str(PAIR), "--rel-tol=-1e-3", "--no-engine"], "--rel-tol: -1e-3: expected a finite number > 0"),
    (["verify", str(PAIR), "--engine-tol=nan"], "--engine-tol: nan: expected a finite number > 0"),
    (["tumble", "--step", "0"], "--step: 0: expected a finite number > 0"),
    (["tumble", "--step", "0.0007"], "must be a whole multiple of it"),
    (["tumble", "--step", "100"], "at least 20 steps in a dwell"),
    (["tumble", "--dwell", "-5"], "--dwell: -5: expected a finite number > 0"),
])
def test_options_no_run_can_mean_are_refused(capsys, argv, said):
    assert said in _err(capsys, argv)


def test_verify_refuses_a_run_with_no_step_to_compare(tmp_path, capsys):
    text = PAIR.read_text().replace("step = 0.004 ", "step = 0.004\nstop = 0.003 #", 1).replace("stop = 3.0", "")
    f = tmp_path / "short.toml"
    f.write_text(text)
    err = _err(capsys, ["verify", str(f), "--no-engine"])
    assert "leaves no communication step after t = 0 to compare" in err


def test_verify_refuses_an_aggregate_of_a_signal_it_does_not_record(capsys):
    err = _err(capsys, ["verify", str(PAIR), "--rel-tol", "1e-3", "--no-engine", "--aggregate", "nosuch.sig=sum"])
    assert "--aggregate nosuch.sig: no recorded signal" in err and "imu.gyro.x" in err


def test_system_file_mistakes_name_what_is_wrong(tmp_path, capsys):
    assert "a directory; expected a system file" in _err(capsys, ["run", str(tmp_path)])
    typo = tmp_path / "typo.toml"
    typo.write_text(PAIR.read_text().replace('fmu = "builtin:turntable"', 'fmu = "builtin:turntabel"'))
    assert "builtin:turntabel: expected one of builtin:turntable, builtin:imu" in _err(capsys, ["run", str(typo)])
    opt = tmp_path / "option.toml"
    opt.write_text(PAIR.read_text().replace('role = "imu"', 'role = "imu"\nrole_options = { gyro_ouput = "rate" }'))
    err = _err(capsys, ["run", str(opt)])
    assert "role 'imu' has no option 'gyro_ouput' (did you mean 'gyro_output'?); its options: gyro_output" in err


def test_an_fmu_without_a_binary_for_this_machine_is_named(tmp_path, capsys):
    built = fmu_path("imu", 2)
    other = tmp_path / "win_only.fmu"
    with zipfile.ZipFile(built) as src, zipfile.ZipFile(other, "w") as dst:
        for item in src.infolist():
            name = item.filename.replace("binaries/linux64/", "binaries/win64/")
            dst.writestr(name, src.read(item.filename))
    system = tmp_path / "sys.toml"
    system.write_text(PAIR.read_text().replace('fmu = "builtin:imu"', f'fmu = "{other}"'))
    err = _err(capsys, ["run", str(system), "--out", str(tmp_path / "r.parquet")])
    assert "has no binary for this machine (binaries/linux64/" in err and "its binaries: win64" in err
    shutil.rmtree(tmp_path / "r.parquet", ignore_errors=True)


def test_verify_json_gives_each_signal_as_numbers(tmp_path):
    """CI reads the coupling error per signal, not a printed table: each signal's estimated error,
    order and verdict, the verdict true exactly when the relative error is within the tolerance."""
    import json

    out = tmp_path / "v.json"
    assert main(["verify", str(PAIR), "--rel-tol", "1e-3", "--no-engine", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    sig = {s["name"]: s for s in d["signals"]}
    assert {"imu.gyro.x", "imu.acc.z", "table.outer.angle"} <= set(sig)
    for s in sig.values():
        assert s["ok"] == (s["rel_error"] <= 1e-3), s
    # the gyro's coupling error halves twice with each halving of the step: order near 2 (README)
    assert 1.5 < sig["imu.gyro.x"]["order"] < 2.5


def test_run_refuses_a_recording_name_of_another_format(tmp_path, capsys):
    """run writes Parquet: --out x.csv wrote Parquet bytes under a .csv name."""
    err = _err(capsys, ["run", str(PAIR), "--out", str(tmp_path / "x.csv")])
    assert "--out" in err and "Parquet" in err and not (tmp_path / "x.csv").exists()


def test_verify_notes_an_aggregation_against_the_roles_output_kind(tmp_path, capsys):
    """examples/tumble.toml sums the IMU's increments; the same IMU told to give mean rates
    (role_options) while record.aggregate still sums them fails by the step ratio: verify says
    which aggregation contradicts the role, and the mean passes."""
    text = (ROOT / "examples" / "tumble.toml").read_text()
    assert 'role = "imu"' in text
    text = text.replace('role = "imu"', 'role = "imu"\nrole_options = { gyro_output = "rate", acc_output = "specific_force" }', 1)
    f = tmp_path / "rate.toml"
    f.write_text(text)
    capsys.readouterr()
    assert main(["verify", str(f), "--no-engine"]) == 1
    out = capsys.readouterr().out
    assert "aggregated by 'sum' (record.aggregate or --aggregate), but the unit's role declares them 'mean'" in out
    assert main(["verify", str(f), "--no-engine", "--aggregate", "imu.gyro=mean", "--aggregate", "imu.acc=mean"]) == 0


def test_check_fmu_names_an_unknown_parameter_before_its_verdict(capsys):
    """--parameter of a name the FMU lacks printed ACCEPTED, then failed at the interface cost
    naming a TOML section nobody wrote ('units.imu.parameters') and an odd step."""
    err = _err(capsys, ["check-fmu", str(fmu_path("imu", 2)), "--role", "imu", "--parameter", "gyro.noise.arww=0"])
    assert "--parameter gyro.noise.arww: " in err and "has no parameter 'gyro.noise.arww' (did you mean gyro.noise.arw" in err
    assert "ACCEPTED" not in capsys.readouterr().out
