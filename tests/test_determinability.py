"""Honest estimates on any log (components.estimation.determinability, components.model.plausibility):
what a short log does not determine is named and held, never printed as a value ± 0 or ± nan;
estimates no real IMU has are flagged with the likely cause.

The determined set is checked against the rank of the accelerometer design computed here from the
logged angles with the test's own rotation code: static rows of bias, scale factor and
misalignment, y_p = b + (I + A) g u_p, so parameter k is determined iff its unit vector lies in
the row space of the rows' Jacobian."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from components.cli import main
from components.errors import EstimationError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log, write_log
from components.model.effects import DEFAULT_EFFECTS

ACC = ["acc.bias", "acc.sf", "acc.mis"]
AX = "xyz"


@pytest.fixture(scope="module")
def example(conformance):
    return read_log(conformance / "example")


def _runs(seg):
    out = []
    for i, s in enumerate(seg):
        if not out or out[-1][0] != s:
            out.append([s, i, i + 1])
        else:
            out[-1][2] = i + 1
    return out


def _cut(log, stop: int):
    return dataclasses.replace(log, time=log.time[:stop], gimbal={k: v[:stop] for k, v in log.gimbal.items()},
                               gyro=log.gyro[:stop], acc=log.acc[:stop], temperature=log.temperature[:stop],
                               segment=log.segment[:stop], command={})


def _rot(axis, a):
    axis = np.asarray(axis, float)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


NAMES = [f"acc.bias.{a}" for a in AX] + [f"acc.sf.{a}" for a in AX] + \
    [f"acc.mis.{ij}" for ij in ("xy", "xz", "yx", "yz", "zx", "zy")]


def _independent_acc_design(log, positions) -> np.ndarray:
    """The static rows' Jacobian in the parameters NAMES, from the logged angles."""
    rows = []
    for _, a, b in positions:
        th = log.angles[b - 1]
        C = np.eye(3)
        for axis, t in zip(log.axis_vectors, th):
            C = C @ _rot(axis, t)
        # up in plate (IMU) axes, at its nominal direction: the rests' 1e-7 rad tilts carry no
        # information a plausible parameter could use (calbench holds what they alone would give)
        u = np.round(C.T @ np.array([0.0, 0.0, 1.0]), 6)
        for i in range(3):
            r = np.zeros(12)
            r[i] = 1.0                                  # bias i
            r[3 + i] = u[i]                             # sf i
            for j in range(3):                          # mis ij in the order xy xz yx yz zx zy
                if j != i:
                    r[6 + ["xy", "xz", "yx", "yz", "zx", "zy"].index(AX[i] + AX[j])] = u[j]
            rows.append(r)
    return np.array(rows)


def _rank(M: np.ndarray) -> int:
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > 1e-9 * s[0])) if len(s) and s[0] > 0 else 0


@pytest.mark.parametrize("n_positions", [1, 2, 3, 6])
def test_determined_set_matches_the_rank_of_the_static_design(example, n_positions):
    """As many parameters determined as the rows' rank; together a basis (the held ones lie in
    their span); every parameter the rows identify on its own among them; of two the rows cannot
    tell apart, the vocabulary's later one (a misalignment before a bias) is held."""
    seg = np.asarray(example.segment).astype(str)
    positions = [r for r in _runs(seg) if r[0].startswith("pos")][:n_positions]
    log = _cut(example, positions[-1][2])
    # the moves sweep gravity through further attitudes: leave them out, the rows are the rests'
    moves = sorted({s for s in seg[:positions[-1][2]] if not s.startswith("pos")})
    fit = calibrate(LogData.from_log(log, exclude=moves), ACC)
    J = _independent_acc_design(example, positions)
    rank = _rank(J)
    det = [NAMES.index(p) for p in fit.parameters]
    assert len(det) == rank and _rank(J[:, det]) == rank
    _, s, Vt = np.linalg.svd(J)
    V = Vt[:rank]
    alone = {n for k, n in enumerate(NAMES) if np.linalg.norm(V[:, k]) > 1 - 1e-6}
    assert alone <= set(fit.parameters)
    assert set(fit.determinability.undetermined) == set(NAMES) - set(fit.parameters)
    if n_positions < 6:
        assert all(p.startswith(("acc.sf", "acc.mis")) for p in fit.determinability.undetermined)
    assert np.all(np.isfinite(fit.sigma)) and np.all(fit.sigma > 0)
    if n_positions == 6:      # six positions: everything
        assert not fit.determinability.undetermined


def test_the_command_line_names_what_it_holds_and_never_prints_zero_sigma(example, tmp_path, capsys):
    seg = np.asarray(example.segment).astype(str)
    stop = [r for r in _runs(seg) if r[0].startswith("pos")][2][2]
    write_log(tmp_path / "short", _cut(example, stop))
    assert main(["calibrate", str(tmp_path / "short"), "--out", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    assert "acc.sf.x" in out and "not determined" in out and "needs rests with x up and with x down" in out
    for line in out.splitlines():
        if line.startswith(("gyro.", "acc.")) and "not determined" not in line:
            sigma = float(line.split()[2])
            assert sigma > 0 and math.isfinite(sigma), line
    res = json.loads((tmp_path / "r.json").read_text())
    held = res["determinability"]["undetermined"]
    assert "acc.sf.x" in held and "acc.sf.x" not in res["parameters"]
    assert held["acc.sf.x"]["needs"] == "rests with x up and with x down"
    assert main(["calibrate", str(tmp_path / "short"), "--out", str(tmp_path / "r2.json"),
                 "--undetermined", "refuse"]) == 2
    assert "this log does not determine acc.sf.x" in capsys.readouterr().err


def test_a_one_sample_log_needs_the_noise_and_then_has_no_dof(example, tmp_path, capsys):
    write_log(tmp_path / "one", _cut(example, 1))
    assert main(["calibrate", str(tmp_path / "one"), "--out", str(tmp_path / "r.json")]) == 2
    assert "one.csv: the white-noise level cannot be estimated" in capsys.readouterr().err  # (the file named)
    assert main(["calibrate", str(tmp_path / "one"), "--out", str(tmp_path / "r.json"), "--noise", "navigation"]) == 0
    out = capsys.readouterr().out
    assert "chi2/dof: none (0 dof" in out
    res = json.loads((tmp_path / "r.json").read_text())
    assert res["fit"]["chi2_per_dof"] is None and set(res["parameters"]) == {f"{s}.bias.{a}" for s in ("gyro", "acc")
                                                                             for a in AX}


@pytest.mark.parametrize("mistake, flagged, cause", [
    ("swap gyro x y", "gyro.sf.x", "axes x and y look swapped"),
    ("flip acc z", "acc.sf.z", "sign looks flipped"),
    ("gyro in degrees", "gyro.sf.y", "degrees declared as radians"),
    ("increments as rates", "gyro.sf.z", "increments declared as rates"),
])
def test_impossible_values_are_flagged_with_the_likely_cause(example, tmp_path, capsys, mistake, flagged, cause):
    log = example
    if mistake == "swap gyro x y":
        log = dataclasses.replace(log, gyro=log.gyro[:, [1, 0, 2]])
    elif mistake == "flip acc z":
        log = dataclasses.replace(log, acc=log.acc * [1, 1, -1])
    elif mistake == "gyro in degrees":
        log = dataclasses.replace(log, gyro=np.degrees(log.gyro))
    else:
        log = dataclasses.replace(log, gyro_output="rate")
    write_log(tmp_path / "bad", log)
    assert main(["calibrate", str(tmp_path / "bad"), "--out", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    assert f"IMPLAUSIBLE {flagged}:" in out and cause in out
    assert main(["calibrate", str(tmp_path / "bad"), "--out", str(tmp_path / "r.json"), "--strict"]) == 1
    assert cause in json.loads((tmp_path / "r.json").read_text())["determinability"]["implausible"][flagged]


def test_a_good_log_flags_nothing(example):
    fit = calibrate(LogData.from_log(example), list(DEFAULT_EFFECTS))
    assert not fit.implausible and not fit.weak and not fit.determinability.undetermined
    assert not fit.determinability.confounded


def test_a_table_non_orthogonality_the_imu_mounting_absorbs_is_said_to_be(example, tmp_path, capsys):
    """The middle axis's non-orthogonality about u turns the plate as a rotation of the IMU on it
    would at every attitude this schedule visits: `add table.nonorth` gives it a σ of hundreds of
    arcsec beside fractions for the others, and says it moves with the gyro and the accelerometer
    misalignments together (a common rotation: coefficients ±1); without it nothing is
    confounded (test_a_good_log_flags_nothing)."""
    write_log(tmp_path / "ex", example)
    assert main(["calibrate", str(tmp_path / "ex"), "--out", str(tmp_path / "m.json")]) == 0
    assert main(["add", str(tmp_path / "ex"), "--model", str(tmp_path / "m.json"), "--effect", "table.nonorth",
                 "--out", str(tmp_path / "n.json")]) == 0
    out = capsys.readouterr().out
    got = json.loads((tmp_path / "n.json").read_text())["determinability"]["confounded"]
    # the partners' σ are inflated by it in turn (the confounding is mutual); nothing else is
    assert "table.nonorth.middle.u" in got and all(p == "table.nonorth.middle.u" or ".mis." in p for p in got)
    moves = dict(got["table.nonorth.middle.u"]["moves_with"])
    assert any(p.startswith("gyro.mis") for p in moves) and any(p.startswith("acc.mis") for p in moves)
    assert all(abs(abs(c) - 1.0) < 0.05 for c in moves.values()), moves
    assert "confounded table.nonorth.middle.u: its sigma is" in out


def test_undetermined_refusal_names_the_motion(example):
    seg = np.asarray(example.segment).astype(str)
    stop = [r for r in _runs(seg) if r[0].startswith("pos")][0][2]
    with pytest.raises(EstimationError, match=r"acc.sf.x \(not seen by this log; needs rests with x up"):
        calibrate(LogData.from_log(_cut(example, stop)), ACC, undetermined="refuse")


def test_a_corrupt_value_is_one_clear_error_and_a_mask_lets_the_rest_calibrate(example, tmp_path, capsys):
    """One 1e308 in a gyro column was an SVD failure traceback: now one line naming the sample;
    masked, the rest of the log calibrates."""
    g = example.gyro.copy()
    g[1000, 0] = 1e308
    bad = dataclasses.replace(example, gyro=g)
    write_log(tmp_path / "huge", bad)
    assert main(["calibrate", str(tmp_path / "huge"), "--out", str(tmp_path / "r.json")]) == 2
    err = capsys.readouterr().err
    assert "sample 1001 (t = 5.005 s), column gyro_x: 1e+308 per 0.005 s" in err and "Traceback" not in err
    t = example.time[1000]
    assert main(["calibrate", str(tmp_path / "huge"), "--out", str(tmp_path / "r.json"),
                 "--exclude", f"{t - 1e-4}:{t + 1e-4}"]) == 0


def test_a_scale_mixup_is_named_for_the_sensor_it_can_happen_to():
    """A gyro's output 10 times its motion (a pulse count weight off by ten) was named "g declared
    as m/s²", a mix-up only an accelerometer can have; each sensor gets its own."""
    from components.model.plausibility import implausible

    got = implausible({"gyro.sf.x": 9.0, "acc.sf.y": 9.80665 - 1, "gyro.sf.z": 180 / math.pi - 1}, 0.005)
    assert "a unit prefix or a pulse count weight off by 10^1" in got["gyro.sf.x"], got
    assert "g declared as m/s²" in got["acc.sf.y"], got
    assert "degrees declared as radians" in got["gyro.sf.z"], got


def test_a_confounded_parameter_is_named_with_what_it_moves_with():
    """Columns a, b and c = k (a + b + ε d) (a, b, d orthonormal) beside an orthogonal column e:
    the least-squares σ of c with the others free is 1/(k ε) (its part outside their span), alone
    1/|c| = 1/(k √(2 + ε²)), so it is √(2 + ε²)/ε times larger; one unit of c looks like k units
    of a plus k of b; e is not confounded. (Whitened columns of 1e6 a unit: σ well inside the
    plausible limits of the names they are given.)"""
    from components.estimation.determinability import CONFOUNDED, assess

    rng = np.random.default_rng(2)
    Q, _ = np.linalg.qr(rng.standard_normal((400, 4)))
    a, b, d, e = Q.T * 1e6
    eps, k = 0.01, 100.0
    names = ["acc.bias.x", "acc.bias.y", "acc.bias.z", "gyro.bias.x"]
    det = assess(np.column_stack([a, b, k * (a + b + eps * d), e]), names)
    assert det.determined == names and "gyro.bias.x" not in det.confounded
    ratio, like = det.confounded["acc.bias.z"]
    assert ratio == pytest.approx(math.sqrt(2 + eps**2) / eps, rel=1e-6) and ratio > CONFOUNDED
    assert dict(like) == pytest.approx({"acc.bias.x": k, "acc.bias.y": k}, rel=1e-6)
    why = det.describe_confounded("acc.bias.z")
    assert why.startswith("its sigma is 141 x") and "acc.bias.x (+100)" in why and "acc.bias.y (+100)" in why
    # far from the threshold: nothing said
    mild = assess(np.column_stack([a, b, a + b + 0.5 * d, e]), names)
    assert mild.confounded == {}
