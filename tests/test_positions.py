"""Calibration without a turntable (components.estimation.positions) on a simulated handheld
session: the turntable FMU only plays the hand. It rests in ten random attitudes and turns once
about the plate's x, y and z between rests; the calibration then gets the increments, the
segment labels and what each label is — never the gimbal angles.

The truth is the IMU FMU's injected parameters, brought into the method's gauge here with the
test's own QR factorisation (I + A = L Q, L lower triangular); the cross-check is an independent
accelerometer calibration written below (the magnitude cost of Tedaldi et al. 2014 / imu_tk,
with an upper-triangular K, converted to the gauge the same way)."""
import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.stats import chi2

from components.control.schedule import schedule_from_dict
from components.errors import EstimationError
from components.estimation.positions import calibrate_positions
from components.model.noise import NoiseModel
from components.model.result import CalibrationResult
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

AX = "xyz"
DEG = math.pi / 180
LAT = 39.9
INJECTED = {
    "acc.bias.x": "2 mg", "acc.bias.y": "-1.5 mg", "acc.bias.z": "1 mg",
    "acc.sf.x": "2000 ppm", "acc.sf.y": "-1500 ppm", "acc.sf.z": "1000 ppm",
    "acc.mis.xy": "1000 arcsec", "acc.mis.xz": "-800 arcsec", "acc.mis.yx": "600 arcsec",
    "acc.mis.yz": "-1000 arcsec", "acc.mis.zx": "900 arcsec", "acc.mis.zy": "-700 arcsec",
    "gyro.bias.x": "20 deg/h", "gyro.bias.y": "-15 deg/h", "gyro.bias.z": "10 deg/h",
    "gyro.sf.x": "1000 ppm", "gyro.sf.y": "-800 ppm", "gyro.sf.z": "600 ppm",
    "gyro.mis.xy": "1000 arcsec", "gyro.mis.xz": "-700 arcsec", "gyro.mis.yx": "500 arcsec",
    "gyro.mis.yz": "-900 arcsec", "gyro.mis.zx": "800 arcsec", "gyro.mis.zy": "-600 arcsec",
}
NOISE = {"gyro.noise.arw": "0.2 deg/sqrt(h)", "acc.noise.vrw": "100 ug/sqrt(Hz)"}
ARW = 0.2 * DEG / 60            # rad/sqrt(s)
VRW = 100e-6 * 9.80665          # m/s/sqrt(s)
DWELL = 20.0


def _attitudes(seed: int = 7, n: int = 10):
    """(outer, middle, inner) [deg] uniformly over the sphere of plate-z directions; the 2nd and
    5th have inner = 0 and -90, so that a turn of the middle axis is a turn about plate x and y."""
    rng = np.random.default_rng(seed)
    att = [[rng.uniform(-180, 180), math.degrees(math.acos(rng.uniform(-1, 1))), rng.uniform(-180, 180)]
           for _ in range(n)]
    att[1][2] = 0.0
    att[4][2] = -90.0
    return att


# after which position which turn: (table axis, rate [deg/s], label, body axis, angle [deg])
TURNS = {2: ("middle", 30.0, "rotX", "x", 360.0),
         5: ("middle", 30.0, "rotY", "y", 360.0),
         8: ("inner", -30.0, "rotZ", "z", -360.0)}


def _schedule(att) -> dict:
    steps = []
    for p, a in enumerate(att, start=1):
        lab = f"pos{p:02d}"
        steps += [{"kind": "index", "angles_deg": [float(x) for x in a], "label": lab},
                  {"kind": "dwell", "duration": DWELL, "label": lab}]
        if p in TURNS:
            axis, rate, rl, _, _ = TURNS[p]
            steps += [{"kind": "rotate", "axis": axis, "rate_dps": rate, "turns": 1, "label": rl},
                      {"kind": "dwell", "duration": DWELL, "label": lab + "b"}]
    return {"schedule": {"name": "handheld", "description": "random rests and three 360 deg turns"},
            "steps": steps}


@pytest.fixture(scope="module")
def session():
    att = _attitudes()
    sc = scenario_from_dict({
        "scenario": {"name": "handheld", "step": 0.005, "seed": 5},
        "schedule": {"name": "six_position"},     # replaced below by the inline schedule
        "site": {"latitude_deg": LAT, "height_m": 50.0},
        "turntable": {"fmu": "builtin:turntable"},
        "imu": {"fmu": "builtin:imu", "effects": INJECTED, "noise": NOISE},
    }, source="test_positions")
    sc = dataclasses.replace(sc, schedule=schedule_from_dict(_schedule(att), "handheld"))
    run = run_scenario(sc, progress=False)
    log = run.log
    # what a handheld log has: no angles; moves excluded; rests of unknown attitude; turns
    labels = np.asarray(log.segment).astype(str)
    kinds = {lab: {"kind": "excluded"} for lab in set(labels) if lab.startswith("move-")}
    kinds.update({lab: {"kind": "static"} for lab in set(labels) if lab.startswith("pos")})
    kinds.update({rl: {"kind": "rotation", "axis": ax, "angle_deg": ang} for _, _, rl, ax, ang in TURNS.values()})
    return {"time": np.asarray(log.time), "gyro": log.gyro_increment(), "acc": log.acc_increment(),
            "segment": labels, "kinds": kinds, "gravity": log.gravity, "latitude": LAT * DEG,
            "truth": run.truth["effects"], "attitudes": att}


def _fit(s, **kw):
    args = dict(latitude=s["latitude"], gravity=s["gravity"])
    args.update(kw)
    kinds = args.pop("kinds", s["kinds"])
    return calibrate_positions(s["time"], s["gyro"], s["acc"], s["segment"], kinds, **args)


def _matrix(values: dict, sensor: str) -> np.ndarray:
    return np.eye(3) + np.array([[values.get(f"{sensor}.sf.{a}" if a == b else f"{sensor}.mis.{a}{b}", 0.0)
                                  for b in AX] for a in AX])


def _lower_factor(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M = L Q with L lower triangular (positive diagonal) and Q a rotation."""
    q, r = np.linalg.qr(M.T)
    s = np.diag(np.sign(np.diag(r)))
    return (s @ r).T, s @ q.T


def _in_gauge(values: dict) -> dict:
    """The accelerometer parameters of a triad I + A as the method's gauge reports them."""
    L, _ = _lower_factor(_matrix(values, "acc"))
    out = dict(values)
    for i, a in enumerate(AX):
        for j, b in enumerate(AX):
            out[f"acc.sf.{a}" if i == j else f"acc.mis.{a}{b}"] = L[i, j] - (i == j)
    return out


def _rot(axis: str, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _up_of(att_deg) -> np.ndarray:
    """Plate-frame up vector of a (outer, middle, inner) attitude of the default table (outer z,
    middle x, inner z, level base)."""
    o, m, i = (x * DEG for x in att_deg)
    return (_rot("z", o) @ _rot("x", m) @ _rot("z", i)).T @ np.array([0.0, 0.0, 1.0])


# ----------------------------------------------------------------------------- 1. recovery
def test_handheld_session_recovers_the_truth_in_the_gauge(session):
    fit = _fit(session)
    truth = _in_gauge(session["truth"])
    assert len(fit.parameters) == 21 and not fit.undetermined
    assert set(fit.held) == {"acc.mis.xy", "acc.mis.xz", "acc.mis.yz"}
    assert not set(fit.held) & set(fit.parameters)
    z = {p: (v - truth.get(p, 0.0)) / s for p, v, s in zip(fit.parameters, fit.value, fit.sigma)}
    assert max(abs(x) for x in z.values()) < 4.0, z
    # the σ are those of a MEMS session, not vacuous: 1000 ppm / 1000" errors found to a few %
    sig = dict(zip(fit.parameters, fit.sigma))
    assert sig["gyro.sf.x"] < 100e-6 and sig["gyro.mis.xy"] < 20 * DEG / 3600 and sig["acc.sf.y"] < 300e-6
    # χ²/dof in its two-sided 99.9 % band
    lo, hi = chi2.ppf([0.0005, 0.9995], fit.dof) / fit.dof
    assert lo < fit.chi2 / fit.dof < hi, (fit.chi2 / fit.dof, lo, hi)
    # 13 rests (10 attitudes, three of them again after a full turn), 3 turns; the moves left out
    assert len(fit.positions) == 13 and len(fit.rotations) == 3
    assert sum(v for k, v in fit.excluded.items() if k.startswith("move-")) > 0


def test_attitudes_are_the_plates_rotated_by_the_gauge(session):
    """The estimated up vectors are the true ones (from the schedule's angles, which the fit
    never saw) turned by the rotation Q of I + A = L Q: the gauge is what docs/positions.md says."""
    fit = _fit(session)
    _, Q = _lower_factor(_matrix(session["truth"], "acc"))
    by_name = {p.name: p for p in fit.positions}
    for k, att in enumerate(session["attitudes"], start=1):
        for name in (f"pos{k:02d}", f"pos{k:02d}b"):
            if name in by_name:
                p = by_name[name]
                err = math.degrees(math.acos(min(1.0, float(p.up @ (Q @ _up_of(att))))))
                assert err < 4 * p.up_sigma_deg + 1e-4, (name, err, p.up_sigma_deg)


def test_full_turns_return_and_leave_white_residuals(session):
    fit = _fit(session)
    for r in fit.rotations:
        assert r.end_mismatch_deg < 0.05, (r.name, r.end_mismatch_deg)
        # one turn per axis: nine rows for the nine gyro scale factors and misalignments, fitted
        # exactly (no check of the gyro model; docs/positions.md: turn twice per axis for one)
        assert np.all(np.abs(r.normalized) < 1e-2), (r.name, r.normalized)
        # the turn's Earth-rate share along its axis, Ω T cos(axis, north-ish): not negligible
        assert np.linalg.norm(r.earth) > 1e-4
    for p in fit.positions:
        assert 0.7 < p.chi2 / p.rows < 1.4, (p.name, p.chi2 / p.rows)


def test_given_white_noise_model_keeps_chi2_in_band(session):
    dt = float(np.median(np.diff(session["time"])))
    noise = NoiseModel.white([ARW * math.sqrt(dt)] * 3 + [VRW * math.sqrt(dt)] * 3, dt, source="truth")
    fit = _fit(session, noise=noise)
    lo, hi = chi2.ppf([0.0005, 0.9995], fit.dof) / fit.dof
    assert lo < fit.chi2 / fit.dof < hi
    assert "given noise model" in fit.noise_source
    np.testing.assert_allclose(fit.sigma_gyro, ARW * math.sqrt(dt), rtol=1e-12)


# ----------------------------------------------------------------------------- 2. cross-check
def _tedaldi_accelerometer(s) -> dict:
    """Independent multi-position accelerometer calibration: per rest the mean specific force
    f_p; minimise Σ_p (|K⁻¹ (f_p − b)| − g)² over b and an upper-triangular K (Tedaldi et al.
    2014's form); returned in the lower-triangular gauge."""
    t, acc, seg = s["time"], s["acc"], s["segment"]
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    means = []
    for lab in sorted(set(seg)):
        if lab.startswith("pos"):
            m = seg == lab
            means.append(acc[m].sum(axis=0) / dt[m].sum())
    F = np.array(means)
    g = s["gravity"]

    def unpack(x):
        K = np.array([[1 + x[0], x[3], x[4]], [0, 1 + x[1], x[5]], [0, 0, 1 + x[2]]])
        return K, x[6:9]

    def res(x):
        K, b = unpack(x)
        return np.linalg.norm(np.linalg.solve(K, (F - b).T), axis=0) - g

    sol = least_squares(res, np.zeros(9), x_scale=np.r_[[1e-3] * 6, [1e-2] * 3], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    K, b = unpack(sol.x)
    L, _ = _lower_factor(K)
    out = {f"acc.bias.{a}": float(b[i]) for i, a in enumerate(AX)}
    for i, a in enumerate(AX):
        for j, c in enumerate(AX):
            if j <= i:
                out[f"acc.sf.{a}" if i == j else f"acc.mis.{a}{c}"] = float(L[i, j] - (i == j))
    return out


def test_same_accelerometer_parameters_as_an_independent_magnitude_calibration(session):
    fit = _fit(session)
    other = _tedaldi_accelerometer(session)
    est, sig = fit.values(), fit.sigmas()
    acc = [p for p in fit.parameters if p.startswith("acc.")]
    assert sorted(acc) == sorted(other)
    diff = {p: (est[p] - other[p]) / sig[p] for p in acc}
    assert max(abs(d) for d in diff.values()) < 0.05, diff


# ----------------------------------------------------------------------------- 3. what the data cannot give
def _cut(s, last_label: str) -> dict:
    """The session up to the end of a label's last sample."""
    stop = int(np.nonzero(s["segment"] == last_label)[0][-1]) + 1
    return {**s, "time": s["time"][:stop], "gyro": s["gyro"][:stop], "acc": s["acc"][:stop],
            "segment": s["segment"][:stop]}


def test_three_positions_are_a_clear_error(session):
    s = _cut(session, "pos03")
    with pytest.raises(EstimationError, match=r"distinct attitude.*at least 9 positions"):
        _fit(s)
    # with the accelerometer effects left out, three rests still give the gyro bias, and the
    # gyro parameters no turn excites are named as undetermined
    kinds = {k: v for k, v in s["kinds"].items()}
    fit = _fit(s, kinds=kinds, effects=["gyro.bias", "gyro.sf", "gyro.mis"])
    assert set(fit.undetermined) == {"gyro.sf.y", "gyro.sf.z", "gyro.mis.xy", "gyro.mis.xz", "gyro.mis.yz",
                                     "gyro.mis.zy"}
    assert fit.parameters == ["gyro.bias.x", "gyro.bias.y", "gyro.bias.z", "gyro.sf.x", "gyro.mis.yx",
                              "gyro.mis.zx"]


def test_gyro_axes_without_a_turn_are_reported_undetermined(session):
    kinds = dict(session["kinds"], rotZ={"kind": "excluded"})
    fit = _fit(session, kinds=kinds)
    assert set(fit.undetermined) == {"gyro.sf.z", "gyro.mis.xz", "gyro.mis.yz"}
    assert not set(fit.undetermined) & set(fit.parameters)
    assert np.all(np.isfinite(fit.sigma)) and np.all(fit.sigma > 0)
    text = "\n".join(fit.lines())
    assert "nan" not in text and "not determined by these data (not estimated): gyro.mis.xz" in text
    truth = _in_gauge(session["truth"])
    z = [(v - truth[p]) / s for p, v, s in zip(fit.parameters, fit.value, fit.sigma)]
    assert max(map(abs, z)) < 4


def test_result_file_never_carries_a_held_or_undetermined_parameter(session, tmp_path):
    kinds = dict(session["kinds"], rotZ={"kind": "excluded"})
    res = _fit(session, kinds=kinds).to_result()
    assert res.method == "positions"
    path = res.save(tmp_path / "positions.json")
    back = CalibrationResult.load(path)
    assert back.method == "positions"
    for p in ("acc.mis.xy", "acc.mis.xz", "acc.mis.yz", "gyro.sf.z", "gyro.mis.xz", "gyro.mis.yz"):
        assert p not in back.values
    assert all(math.isfinite(s) and s > 0 for s in back.sigmas.values())
    block = back.extra["positions"]
    assert set(block["held"]) == {"acc.mis.xy", "acc.mis.xz", "acc.mis.yz"}
    assert set(block["undetermined"]) == {"gyro.sf.z", "gyro.mis.xz", "gyro.mis.yz"}
    assert len(block["attitudes"]) == 13 and len(block["rotations"]) == 2
    assert back.fit["dof"] > 0 and back.correlation.shape == (len(back.values),) * 2


# ----------------------------------------------------------------------------- descriptions the data contradict
def test_up_hints_are_checked_against_the_data(session):
    fit = _fit(session)
    ups = {p.name: p.up for p in fit.positions}
    near = {name: "xyz"[int(np.argmax(np.abs(u)))] for name, u in ups.items()}
    sign = {name: "" if ups[name]["xyz".index(a)] > 0 else "-" for name, a in near.items()}
    kinds = dict(session["kinds"])
    kinds["pos09"] = {"kind": "static", "up": sign["pos09"] + near["pos09"]}
    hinted = _fit(session, kinds=kinds)
    p9 = next(p for p in hinted.positions if p.name == "pos09")
    assert p9.hint_angle_deg < 45
    wrong = "" if sign["pos09"] == "-" else "-"
    kinds["pos09"] = {"kind": "static", "up": wrong + near["pos09"]}
    with pytest.raises(EstimationError, match=r"static 'pos09'.*from the stated up"):
        _fit(session, kinds=kinds)


def test_a_turn_of_the_wrong_sign_is_a_clear_error(session):
    kinds = dict(session["kinds"], rotZ={"kind": "rotation", "axis": "z", "angle_deg": 360})
    with pytest.raises(EstimationError, match=r"rotation 'rotZ': the gyros turn -36\d\.\d° .* says \+360"):
        _fit(session, kinds=kinds)
    # the same turn stated as +360 deg about -z is the same physical turn: the same fit
    kinds = dict(session["kinds"], rotZ={"kind": "rotation", "axis": "-z", "angle_deg": 360})
    a, b = _fit(session), _fit(session, kinds=kinds)
    np.testing.assert_allclose(a.value, b.value, rtol=0, atol=1e-3 * a.sigma.min())


def test_a_turn_must_go_from_rest_to_rest(session):
    kinds = dict(session["kinds"], pos02={"kind": "excluded"})
    with pytest.raises(EstimationError, match=r"rotation 'rotX'.*before it comes segment 'pos02' \(excluded\)"):
        _fit(session, kinds=kinds)


@pytest.mark.parametrize("bad, match", [
    ({"kind": "rest"}, r"segment 'pos01': expected \{'kind'"),
    ({"kind": "static", "up": "w"}, r"segment 'pos01': up = 'w'"),
    ({"kind": "static", "up": [1, 1, 0]}, r"expected a unit vector"),
    ({"kind": "rotation", "axis": "x"}, r"needs 'axis'.*'angle_deg'"),
    ({"kind": "rotation", "axis": "x", "angle_deg": 0}, r"angle_deg = 0"),
    ({"kind": "static", "angle_deg": 90}, r"unknown key\(s\) \['angle_deg'\]"),
])
def test_segment_descriptions_are_checked(session, bad, match):
    with pytest.raises(EstimationError, match=match):
        _fit(session, kinds=dict(session["kinds"], pos01=bad))


def test_gaps_and_the_missing_latitude(session):
    valid = np.ones(len(session["time"]), bool)
    rot_x = np.nonzero(session["segment"] == "rotX")[0]
    valid[rot_x[len(rot_x) // 2]] = False                     # a gap inside a turn: it is left out
    pos = np.nonzero(session["segment"] == "pos04")[0]
    valid[pos[100:300]] = False                               # a gap at rest: the rest still counts
    fit = _fit(session, valid=valid)
    assert [r.name for r in fit.rotations] == ["rotY", "rotZ"]
    assert any("rotation 'rotX' left out" in n for n in fit.notes)
    assert fit.excluded["(valid = False)"] == 201
    assert next(p for p in fit.positions if p.name == "pos04").samples == len(pos) - 200
    with pytest.raises(EstimationError, match="magnitude of gravity"):
        _fit(session, latitude=None, gravity=None)
    fit = _fit(session, latitude=None)
    assert any("Earth rate" in n and "not modelled" in n for n in fit.notes)
    assert all(p.north is None for p in fit.positions)


def test_the_result_corrects_a_log_with_calbenchs_own_correction(session):
    """The result file is an ordinary calibration model: components.model.correct applies it,
    after which every rest reads gravity's magnitude and every turn its angle plus the Earth's
    share, to the noise."""
    from components.model.correct import correct_increments

    fit = _fit(session)
    t = session["time"]
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    g_inc, a_inc = correct_increments(fit.to_result(), session["gyro"], session["acc"], dt, None)
    seg, g = session["segment"], session["gravity"]
    raw = []
    for lab in sorted(set(seg)):
        if lab.startswith("pos"):
            m = seg == lab
            T = dt[m].sum()
            raw.append(np.linalg.norm(session["acc"][m].sum(axis=0)) / T - g)
            fixed = np.linalg.norm(a_inc[m].sum(axis=0)) / T - g
            assert abs(fixed) < 4 * VRW / math.sqrt(T), (lab, fixed)
    assert np.max(np.abs(raw)) > 0.04                          # 4 mg before
    earth = {r.name: r.earth for r in fit.rotations}
    for _, _, rl, axis, angle in TURNS.values():
        m = seg == rl
        k = "xyz".index(axis)
        turned = g_inc[m].sum(axis=0)[k]
        assert abs(turned - angle * DEG - earth[rl][k]) < 4 * ARW * math.sqrt(dt[m].sum()), (rl, turned)
