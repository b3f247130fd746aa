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
    no_angles = dataclasses.replace(log, gimbal={}, command={}, axis_names=[], axis_vectors=np.zeros((0, 3)),
                                    segments=kinds)
    d = tmp_path_factory.mktemp("handheld")
    write_log(d / "hh", no_angles, "parquet")
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
