"""Logs without table angles through the command line: a simulated handheld session with a hidden
accelerometer K2 (24 rests of unknown attitude, three 360° turns, hand moves excluded) written as
a calbench-log/2 file; calibrate, compare, diagnose and add on it.

Checks against independent computations: the generic rows (any effect of the vocabulary, its
regressors on the rebuilt motion) against the positions method's own model on the three default
effects; the K2 fit against an accelerometer-only multi-position fit with K2 written here
(per-rest means, two angles per rest, scipy's least_squares); the truth in the method's gauge
(tests/test_positions.py)."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.stats import chi2
from test_positions import AX, INJECTED, LAT, NOISE, TURNS, _attitudes, _in_gauge, _lower_factor, _schedule

from components.cli import main
from components.control.schedule import schedule_from_dict
from components.estimation.log_data import LogData
from components.estimation.positions import calibrate_positions
from components.estimation.positions_effects import refine_positions
from components.logs.logfile import read_log, write_log
from components.model.effects import DEFAULT_EFFECTS
from components.model.result import CalibrationResult
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

K2_Z = 600e-6 / 9.80665  # 600 ug/g² in SI [s²/m]


@pytest.fixture(scope="module")
def handheld(tmp_path_factory):
    att = _attitudes(seed=7, n=24)
    effects = dict(INJECTED, **{"acc.k2.z": "600 ug/g2"})
    sc = scenario_from_dict({
        "scenario": {"name": "handheld-k2", "step": 0.005, "seed": 11},
        "schedule": {"name": "six_position"},
        "site": {"latitude_deg": LAT, "height_m": 50.0},
        "turntable": {"fmu": "builtin:turntable"},
        "imu": {"fmu": "builtin:imu", "effects": effects, "noise": NOISE},
    }, source="test_positions_effects")
    sc = dataclasses.replace(sc, schedule=schedule_from_dict(_schedule(att), "handheld"))
    run = run_scenario(sc, progress=False)
    log = run.log
    labels = np.asarray(log.segment).astype(str)
    kinds = {lab: {"kind": "excluded"} for lab in sorted(set(labels)) if lab.startswith("move-")}
    kinds.update({lab: {"kind": "static"} for lab in sorted(set(labels)) if lab.startswith("pos")})
    kinds.update({rl: {"kind": "rotation", "axis": ax, "angle_deg": ang} for _, _, rl, ax, ang in TURNS.values()})
    no_angles = dataclasses.replace(log, gimbal={}, command={}, axis_names=[], axis_vectors=np.zeros((0, 3)), encoder_resolution=None,
                                    segments=kinds)
    d = tmp_path_factory.mktemp("handheld")
    write_log(d / "hh", no_angles, "parquet")
    write_log(d / "hh_table", log, "parquet")  # the same session as logged with its table angles
    return {"dir": d, "stem": d / "hh", "truth": run.truth["effects"], "log": read_log(d / "hh")}


def _run(capsys, *argv) -> str:
    assert main([str(a) for a in argv]) == 0
    return capsys.readouterr().out


def test_the_file_has_no_angles_and_says_what_each_label_is(handheld):
    meta = json.loads((handheld["dir"] / "hh.json").read_text())
    assert meta["format"] == "calbench-log/2" and meta["table"]["axes"] == []
    assert not handheld["log"].has_table and handheld["log"].segments["rotX"]["kind"] == "rotation"


def test_generic_rows_give_the_positions_methods_estimate(handheld):
    """Two implementations of the same model: the method's own (products (I + K) x written out)
    and the vocabulary's regressors on the rebuilt motion; the same estimate within 1e-3 σ."""
    data = LogData.from_log(handheld["log"])
    base = calibrate_positions(data.time, data.gyro, data.acc, data.segment, data.segments, valid=data.usable,
                               latitude=data.geometry.latitude, gravity=data.geometry.gravity)
    again = refine_positions(data, base, list(DEFAULT_EFFECTS))
    assert sorted(again.parameters) == sorted(base.parameters)
    v, s = again.values(), again.sigmas()
    for p, v0, s0 in zip(base.parameters, base.value, base.sigma):
        assert abs(v[p] - v0) < 1e-3 * s0, (p, v[p], v0, s0)
        assert abs(s[p] / s0 - 1) < 1e-3, (p, s[p], s0)
    assert abs(again.chi2 - base.chi2) < 1e-3 * base.dof


def _independent_k2(log) -> dict:
    """Accelerometer bias, lower-triangular (I + A) and K2 from the rests' mean specific force,
    with each rest's up vector as two angles: least squares written here, not calbench's."""
    seg = np.asarray(log.segment).astype(str)
    dt = np.diff(log.time, prepend=log.time[0] - log.dt)
    acc = log.acc_increment()
    F = np.array([acc[seg == lab].sum(axis=0) / dt[seg == lab].sum() for lab in sorted(set(seg))
                  if lab.startswith("pos")])
    g = log.gravity
    P = len(F)

    def unpack(x):
        L = np.eye(3) + np.array([[x[0], 0, 0], [x[3], x[1], 0], [x[4], x[5], x[2]]])
        return L, x[6:9], x[9:12], x[12:].reshape(P, 2)

    def up(ang):
        th, ph = ang[:, 0], ang[:, 1]
        return np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])

    def res(x):
        L, b, k2, ang = unpack(x)
        f = g * up(ang)
        return ((f @ L.T) + b + k2 * f ** 2 - F).ravel()

    u0 = F / np.linalg.norm(F, axis=1)[:, None]
    ang0 = np.column_stack([np.arccos(np.clip(u0[:, 2], -1, 1)), np.arctan2(u0[:, 1], u0[:, 0])])
    sol = least_squares(res, np.concatenate([np.zeros(12), ang0.ravel()]), xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        x_scale=np.concatenate([[1e-3] * 6, [1e-2] * 3, [1e-5] * 3, [1.0] * 2 * P]))
    L, b, k2, _ = unpack(sol.x)
    out = {f"acc.bias.{a}": b[i] for i, a in enumerate(AX)}
    out.update({f"acc.k2.{a}": k2[i] for i, a in enumerate(AX)})
    for i, a in enumerate(AX):
        for j, c in enumerate(AX[:i + 1]):
            out[f"acc.sf.{a}" if i == j else f"acc.mis.{a}{c}"] = L[i, j] - (i == j)
    return out


def test_the_loop_on_a_log_without_angles(handheld, capsys):
    """calibrate -> compare (the K2 shows) -> diagnose (K2 among the named, its look-alikes said)
    -> add acc.k2 (χ² back in band, K2 at the truth, the same as an independent fit) -> diagnose
    (nothing more)."""
    d, stem = handheld["dir"], handheld["stem"]
    out = _run(capsys, "calibrate", f"{stem}.parquet", "--out", d / "r0.json")
    assert "no table angles: the positions method" in out and "left out:" in out
    r0 = CalibrationResult.load(d / "r0.json")
    assert r0.method == "positions" and "acc.mis.xy" not in r0.values
    out = _run(capsys, "compare", stem, "--model", d / "r0.json", "--json", d / "c0.json")
    c0 = json.loads((d / "c0.json").read_text())
    band_hi = chi2.ppf(0.9995, c0["dof"]) / c0["dof"]
    assert c0["chi2_per_dof"] > band_hi, c0["chi2_per_dof"]          # the hidden K2 is visible
    out = _run(capsys, "diagnose", stem, "--model", d / "r0.json", "--json", d / "d0.json")
    d0 = json.loads((d / "d0.json").read_text())
    passing = [c["effect"] for c in d0["ranking"] if c["passes"]]
    assert "acc.k2" in passing and d0["verdict"] in ("acc.k2", "acc.sf_asym", "acc.cross")
    if d0["verdict"] != "acc.k2":
        assert "cannot be told apart from acc.k2" in out
    # a look-alike first by chance: the verdict names both, not the first alone
    verdict = next(line for line in out.splitlines() if line.startswith("verdict:"))
    assert "acc.k2" in verdict, verdict
    out = _run(capsys, "add", stem, "--model", d / "r0.json", "--effect", "acc.k2", "--out", d / "r1.json")
    r1 = CalibrationResult.load(d / "r1.json")
    assert [e["model"] for e in r1.extra["ladder"]][-1] == "+ acc.k2"
    lo, hi = r1.fit["chi2_per_dof_band_999"]
    assert lo < r1.fit["chi2_per_dof"] < hi
    assert abs(r1.values["acc.k2.z"] - K2_Z) < 4 * r1.sigmas["acc.k2.z"], (r1.values["acc.k2.z"], K2_Z)
    truth = _in_gauge(handheld["truth"])
    for p in ("acc.bias.x", "acc.sf.y", "acc.mis.zy", "gyro.sf.x", "gyro.mis.yz"):
        assert abs(r1.values[p] - truth[p]) < 4 * r1.sigmas[p], p
    other = _independent_k2(handheld["log"])
    for p, v in other.items():
        assert abs(r1.values[p] - v) < 0.1 * r1.sigmas[p], (p, r1.values[p], v, r1.sigmas[p])
    out = _run(capsys, "diagnose", stem, "--model", d / "r1.json", "--json", d / "d1.json")
    assert json.loads((d / "d1.json").read_text())["verdict"] is None, out
    # no noise term is tested on a log without table angles: the verdict does not claim the noise suffices
    assert "noise terms the model lacks were not tested" in out and "noise model suffices" not in out
    # the page needs table angles: add --report says so before it fits, as compare and diagnose do
    assert main(["add", str(stem), "--model", str(d / "r0.json"), "--effect", "acc.k2", "--out", str(d / "r2.json"),
                 "--report", str(d / "page.html")]) == 2
    assert "add --report: the page needs a log with table angles" in capsys.readouterr().err
    assert not (d / "page.html").exists() and not (d / "r2.json").exists()


def test_exclude_on_the_command_line(handheld, capsys):
    """--exclude a rest by label and a time range: the rest leaves the fit, the counts are said."""
    d, stem = handheld["dir"], handheld["stem"]
    log = handheld["log"]
    t_pos04 = log.time[np.asarray(log.segment) == "pos04"]
    out = _run(capsys, "calibrate", stem, "--out", d / "rx.json", "--exclude", "pos07",
               "--exclude", f"{t_pos04[0]}:{t_pos04[-1]}")
    assert "segment 'pos07' (exclude): 4000" in out and f"t = {t_pos04[0]:g}-{t_pos04[-1]:g} s (exclude): 4000" in out
    names = [a["name"] for a in CalibrationResult.load(d / "rx.json").extra["positions"]["attitudes"]]
    assert "pos07" not in names and "pos04" not in names and "pos06" in names
    # a rest a turn needs cannot go alone
    assert main(["calibrate", str(stem), "--out", str(d / "ry.json"), "--exclude", "pos05"]) == 2
    assert "rotation 'rotY': the static segment before it ('pos05') has no usable samples" in capsys.readouterr().err
    assert main(["calibrate", str(stem), "--out", str(d / "ry.json"), "--exclude", "nope"]) == 2
    assert "exclude 'nope': no segment has this label" in capsys.readouterr().err
    assert main(["calibrate", str(stem), "--out", str(d / "ry.json"), "--exclude", "5:x"]) == 2
    assert "--exclude '5:x': expected a segment label or a time range T0:T1" in capsys.readouterr().err


def test_the_gauge_is_the_lower_triangular_factor(handheld):
    """Sanity of the truth conversion the assertions above rely on: L Q = I + A, L lower triangular."""
    A = np.eye(3) + np.array([[1e-3, 2e-3, -1e-3], [3e-3, -2e-3, 5e-4], [1e-3, 2e-4, 1e-3]])
    L, Q = _lower_factor(A)
    np.testing.assert_allclose(L @ Q, A, atol=1e-15)
    assert abs(L[0, 1]) < 1e-15 and abs(L[0, 2]) < 1e-15 and abs(L[1, 2]) < 1e-15
    assert math.isclose(np.linalg.det(Q), 1.0, rel_tol=1e-12)


def _as_pulse_counts(log, gyro_count: float, acc_count: float):
    """*log* (increments) as the whole pulse counts of a logger with those count weights: each
    sample the counts the running sum has crossed."""
    def counts(x, w):
        return np.diff(np.floor(np.cumsum(x, axis=0) / w), axis=0, prepend=0.0)

    return dataclasses.replace(log, gyro=counts(log.gyro, gyro_count), acc=counts(log.acc, acc_count),
                               gyro_output="counts", acc_output="counts", gyro_count_rad=gyro_count,
                               acc_count_mps=acc_count)


def test_pulse_counts_take_their_white_level_from_the_rests(handheld, capsys):
    """Counts five times a sample's noise: the white level beside the quantization is read in the
    static segments, not over the turns and hand moves between them (which made it ~300 times
    too large on a vendor's counts log: χ²/dof 0.015 and every σ that much too wide). The counts'
    σ stay those of the increments' log (within the quantization's share) and χ² in its band."""
    d = handheld["dir"]
    write_log(d / "counts", _as_pulse_counts(handheld["log"], 2e-5, 3e-4), "parquet")
    effects = ",".join([*DEFAULT_EFFECTS, "acc.k2"])  # the log's hidden K2 too: a complete model
    _run(capsys, "calibrate", d / "counts.parquet", "--out", d / "rc.json", "--effects", effects)
    _run(capsys, "calibrate", f"{handheld['stem']}.parquet", "--out", d / "ri.json", "--effects", effects)
    rc, ri = CalibrationResult.load(d / "rc.json"), CalibrationResult.load(d / "ri.json")
    lo, hi = rc.fit["chi2_per_dof_band_999"]
    assert lo < rc.fit["chi2_per_dof"] < hi, rc.fit["chi2_per_dof"]
    for p in ("gyro.bias.z", "gyro.sf.x", "acc.bias.z", "acc.sf.y"):
        assert 0.8 < rc.sigmas[p] / ri.sigmas[p] < 1.5, (p, rc.sigmas[p], ri.sigmas[p])


def test_a_given_coloured_noise_model_is_used_and_kept(handheld, capsys):
    """calibrate --noise with a bias instability: the rows are whitened with it (the σ widen), the
    result keeps it, and diagnose without --noise reads it from there (the same χ² as told it)."""
    d, stem = handheld["dir"], handheld["stem"]
    noise = ["--noise", "gyro.noise.arw=0.2 deg/sqrt(h)", "--noise", "acc.noise.vrw=100 ug/sqrt(Hz)",
             "--noise", "acc.noise.bi=300 ug"]
    _run(capsys, "calibrate", f"{stem}.parquet", "--out", d / "rw.json", *noise[:4])
    _run(capsys, "calibrate", f"{stem}.parquet", "--out", d / "rn.json", *noise)
    rw, rn = CalibrationResult.load(d / "rw.json"), CalibrationResult.load(d / "rn.json")
    assert rn.noise_model() is not None and rn.noise_model().coloured
    assert rn.sigmas["acc.bias.z"] > 1.5 * rw.sigmas["acc.bias.z"]
    _run(capsys, "diagnose", stem, "--model", d / "rn.json", "--json", d / "dn_own.json")
    _run(capsys, "diagnose", stem, "--model", d / "rn.json", "--json", d / "dn_told.json", *noise)
    own, told = (json.loads((d / f).read_text()) for f in ("dn_own.json", "dn_told.json"))
    assert own["base_chi2_per_dof"] == pytest.approx(told["base_chi2_per_dof"], rel=1e-9)


@pytest.mark.parametrize("axis", [None, 0, 1, 2])
def test_a_reversed_axis_is_named_from_the_earth_rate_at_rest(handheld, axis):
    """At rest f·ω = g Ω sin(latitude) in any attitude: the handheld log as logged gives no finding,
    with one accelerometer axis reversed (a left-handed pair) the finding names that axis."""
    from components.estimation.semantics import check_semantics

    log = handheld["log"]
    if axis is not None:
        acc = log.acc.copy()
        acc[:, axis] *= -1
        log = dataclasses.replace(log, acc=acc)
    found = check_semantics(LogData.from_log(log), log)
    if axis is None:
        assert found == []
    else:
        assert len(found) == 1 and f"{'xyz'[axis]} axis is reversed" in found[0], found


def test_plan_on_a_log_without_angles_is_the_positions_methods_bound(handheld, capsys):
    """plan on the log without angles: each rest's attitude is an unknown of its own, so its bound
    is at least the same session's with table angles (more unknowns never shrink a Cramér–Rao
    bound), and with white noise it is the σ calibrate then reports; the gauge's parameters are
    said to be held, not given a bound."""
    d, stem = handheld["dir"], handheld["stem"]
    white = ["--noise", "gyro.noise.arw=0.2 deg/sqrt(h)", "--noise", "acc.noise.vrw=100 ug/sqrt(Hz)",
             "--noise", "gyro.noise.bi=0", "--noise", "acc.noise.bi=0", "--noise", "gyro.noise.rrw=0",
             "--noise", "acc.noise.rrw=0"]
    effects = ",".join([*DEFAULT_EFFECTS, "acc.k2"])
    out = _run(capsys, "plan", stem, "--effects", effects, "--json", d / "plan.json", *white)
    assert "no table angles: the bound of the positions method" in out
    plan = json.loads((d / "plan.json").read_text())
    _run(capsys, "plan", d / "hh_table", "--effects", effects, "--json", d / "plan_table.json", *white)
    table = json.loads((d / "plan_table.json").read_text())["crb"]
    assert set(plan["held"]) == {"acc.mis.xy", "acc.mis.xz", "acc.mis.yz"}
    for p in ("acc.k2.z", "acc.bias.z", "acc.sf.x", "gyro.bias.x", "gyro.bias.z"):
        assert plan["crb"][p]["sigma"] >= table[p]["sigma"] * (1 - 1e-9), p
    assert plan["crb"]["acc.k2.z"]["sigma"] > 1.5 * table["acc.k2.z"]["sigma"]   # the attitudes cost K2 most
    _run(capsys, "calibrate", f"{stem}.parquet", "--out", d / "rp.json", "--effects", effects, *white)
    fit = CalibrationResult.load(d / "rp.json")
    for p in ("acc.k2.z", "acc.bias.x", "gyro.sf.y"):
        assert plan["crb"][p]["sigma"] == pytest.approx(fit.sigmas[p], rel=1e-6), p


@pytest.mark.parametrize("command", ["compare", "diagnose"])
def test_a_report_of_a_log_without_angles_is_refused_before_the_analysis(handheld, capsys, command):
    """The page needs table angles: said first (exit 2), not after the whole analysis is printed."""
    d, stem = handheld["dir"], handheld["stem"]
    _run(capsys, "calibrate", f"{stem}.parquet", "--out", d / "rr.json")
    assert main([command, str(stem), "--model", str(d / "rr.json"), "--report", str(d / "p.html")]) == 2
    out, err = capsys.readouterr()
    assert f"{command} --report: the page needs" in err and "chi2/dof" not in out, out
    assert not (d / "p.html").exists()
