"""Ready-made system-level configurations (``calbench kf NAME LOG``) and a TOML loader.

- ``seed_001``: seed 001 steps 3–7 on the seed_001 schedule: the CW/CCW closed forms give the
  gyro scale factors and all six misalignments against the table (and the coarse accelerometer
  scale factors), the data are corrected with them, then a filter on the 18-position sequence
  (labels ``sys..``) estimates gyro biases and accelerometer scale factor, all six
  misalignments and bias (9 + 18 states); its scale factors correct the coarse ones (the result
  holds the sum). The gyros, held at their table-referenced misalignments, realise the table
  frame, so all six accelerometer misalignments are observable against it (a real IMU has all
  six; with only the lower three, an injected ``acc.mis.xy`` biased acc.bias.x by 22 σ and the
  gyro biases by 8–14 σ).
- ``seed_001_single``: the single system-level filter on the same 18 positions, all gyro and
  accelerometer bias / scale factor / misalignment states at once (the comparison of the
  seed's claim).
- ``seed_003``: a table stage on S201+S202 (the seed's table-referenced steps: least squares
  with the table angles) for the IMU/table time offset, which the navigation velocity cannot see
  (a shifted IMU record on a stationary base is an equally valid trajectory:
  components.navigation.observability); then the S203 39-state filter (9 nav + gyro bias 3 +
  acc bias 3 + gyro sf/mis 9 + acc sf/mis 6 + inner lever arms 6 + K2 3) on the y-x-z / z-x-y
  excitation (with S202 in front), then the 12-state bias filter (9 nav + 3 gyro biases) on the
  S204 azimuth back-and-forth: its prior is the 39-state result (with correlations), the other
  27 parameters are consider states (kept, their uncertainty accounted for), so its gyro
  biases refine those of S203 consistently.
- ``seed_003_joint``: the same table stage, then one 39-state filter over S202-S204: what the
  seed's split into a 39-state and a 12-state filter gives away (S204's rests and azimuth turns
  also inform the misalignments and lever arms, which the 12-state stage only considers).
- ``seed_003_external``: seed 003's external-table mode: the IMU off the rotation centre adds the
  outer lever arm. The lever model becomes all 9 ``acc.lever.i.k`` (the outer arm r is the
  diagonal ``acc.lever.i.i``; ``acc.lever.i.k`` = r_k + the inner arm of axis i), 9 nav + 33 = 42
  states; what rests is the centre, not the IMU, so the filters observe the position too (its
  displacement (C_b^n − C_b^n(0)) r is what shows r).
- ``psins19``: the 19-position PSINS-style sequence (components/control/schedules/psins19.toml): the
  time offset from the table angles over the whole sequence, then the 39-state filter of seed
  003 on it.

Accelerometer misalignment: when the filter also estimates the gyro misalignments, nothing
but the sensors defines the body frame, so only 3 of the 6 off-diagonal accelerometer terms
are observable (domain.md §4): those configurations keep ``acc.mis.yx, zx, zy`` (the lower
triangle) and 9 gyro sf/mis terms, in the accelerometer-defined frame
(components.navigation.truth_frame turns a simulation's truth into it).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

from components.model.effects import effect_of, parameters_of
from components.navigation.system import Config, Stage

ACC_MIS3 = ["acc.mis.yx", "acc.mis.zx", "acc.mis.zy"]
GYRO9 = parameters_of(["gyro.sf", "gyro.mis"])
ACC_LEVER6 = ["acc.lever.x.y", "acc.lever.x.z", "acc.lever.y.x", "acc.lever.y.z",
              "acc.lever.z.x", "acc.lever.z.y"]


# the least-squares model of a table stage: what the IMU is calibrated for, with the table angles
TABLE_MODEL = ["gyro.bias", "acc.bias", "gyro.sf", "gyro.mis", "acc.sf", "acc.mis", "acc.lever",
               "acc.k2", "imu.time_offset"]


def _time_offset_stage(name: str, window: str | None) -> Stage:
    return Stage("table", name, effects=TABLE_MODEL, parameters=["imu.time_offset"], window=window)


# seed 003's pieces, shared by its three configurations
P39 = (parameters_of(["gyro.bias", "acc.bias"]) + GYRO9 + parameters_of(["acc.sf"]) + ACC_MIS3
       + ACC_LEVER6 + parameters_of(["acc.k2"]))


def _s201_s202_time_offset() -> Stage:
    return _time_offset_stage("S201+S202 table-referenced", r"^(move-)?S20[12]")


def _s203_filter(name: str, parameters: list, window: str, **settings) -> Stage:
    return Stage("kf", name, parameters=list(parameters), window=window, settings={"passes": 3, **settings})


def _s204_bias_filter(**settings) -> Stage:
    return Stage("kf", "S204 12-state bias", parameters=parameters_of(["gyro.bias"]),
                 window=r"^(move-)?S204", settings={"passes": 2, **settings}, consider_earlier=True)


def _seed003() -> Config:
    return Config("seed_003", "seed 003: S201/S202 against the table (time offset), the S203 "
                  "39-state filter, then the S204 12-state bias filter", [
        _s201_s202_time_offset(),
        _s203_filter("S202+S203 39-state", P39, r"^(move-)?S20[23]"),
        _s204_bias_filter(),
    ], schedule="seed_003")


def _seed003_joint() -> Config:
    return Config("seed_003_joint", "seed 003 schedule: time offset against the table, then one "
                  "39-state filter over S202-S204", [
        _s201_s202_time_offset(),
        _s203_filter("S202-S204 39-state", P39, r"^(move-)?S20[234]"),
    ], schedule="seed_003")


def _seed003_external() -> Config:
    p42 = [p for p in P39 if not p.startswith("acc.lever")] + parameters_of(["acc.lever"])
    return Config("seed_003_external", "seed 003 on an external table: time offset against the "
                  "table, the 42-state filter (outer lever arm), the S204 bias filter; position "
                  "observed", [
        _s201_s202_time_offset(),
        _s203_filter("S202+S203 42-state", p42, r"^(move-)?S20[23]", observe_position=True),
        _s204_bias_filter(observe_position=True),
    ], schedule="seed_003")


def _seed001() -> Config:
    p = parameters_of(["gyro.bias", "acc.sf", "acc.mis", "acc.bias"])
    return Config("seed_001", "seed 001: CW/CCW gyro stage, then the 18-position filter", [
        Stage("cwccw", "CW/CCW gyro sf/mis + coarse acc sf", effects=["gyro.sf", "gyro.mis", "acc.sf"]),
        Stage("kf", "18-position", parameters=p, window=r"^(move-)?sys", settings={"passes": 2}),
    ], schedule="seed_001")


def _seed001_single() -> Config:
    p = (parameters_of(["gyro.bias"]) + GYRO9 + parameters_of(["acc.sf"]) + ACC_MIS3
         + parameters_of(["acc.bias"]))
    return Config("seed_001_single", "one system-level filter on the 18 positions", [
        Stage("kf", "18-position single", parameters=p, window=r"^(move-)?sys",
              settings={"passes": 2}),
    ], schedule="seed_001")


def _psins19() -> Config:
    return Config("psins19", "19-position PSINS-style sequence: time offset against the table, "
                  "then the 39-state filter", [
        _time_offset_stage("19-position table-referenced", None),
        Stage("kf", "19-position", parameters=list(P39), window=None, settings={"passes": 3}),
    ], schedule="psins19")


def _psins19_tga() -> Config:
    """psins19 with the gyro–accelerometer time offset (PSINS's tGA) as a 40th state: a late
    accelerometer shows in the navigation velocity at every index (its specific force turns
    before the gyro-integrated attitude does); left out, 1 ms of it made the 39-state filter
    diverge on a noise-free run. On a table log the table stage's imu.time_offset takes both
    offsets' sum (its rows cannot tell them apart), which the filter does not use."""
    return Config("psins19_tga", "psins19 with the gyro-accelerometer time offset as a 40th state", [
        _time_offset_stage("19-position table-referenced", None),
        Stage("kf", "19-position tGA", parameters=list(P39) + ["acc.time_offset"], window=None,
              settings={"passes": 3}),
    ], schedule="psins19")


READY = {"seed_003": _seed003, "seed_003_joint": _seed003_joint,
         "seed_003_external": _seed003_external, "seed_001": _seed001,
         "seed_001_single": _seed001_single, "psins19": _psins19, "psins19_tga": _psins19_tga}

# The prior σ of each effect's parameters for an IMU grade (SI): the configurations are written
# for navigation grade (10 x the vocabulary's typical magnitudes); a MEMS IMU's errors are
# hundreds to thousands of times larger, and a filter told otherwise diverges or clips them.
GRADE_PRIORS = {
    "mems": {
        "gyro.bias": 100 * math.pi / 180 / 3600, "gyro.sf": 5e-3, "gyro.mis": 3e-3,
        "gyro.gsens": 0.1 * math.pi / 180 / 9.80665,
        "acc.bias": 10e-3 * 9.80665, "acc.sf": 5e-3, "acc.mis": 3e-3,
        "acc.k2": 1e-3 / 9.80665, "acc.lever": 0.02, "acc.time_offset": 2e-3, "imu.time_offset": 1e-2,
    },
}
GRADE_ATTITUDE = {"mems": (1e-2, 1e-2, 0.3)}   # initial attitude σ [rad]: a MEMS gyro's heading is rough


def with_grade(config: Config, grade: str) -> Config:
    """*config* with its kf stages' priors (and initial attitude σ) of an IMU *grade*
    ("navigation": as written; "mems")."""
    if grade == "navigation":
        return config
    if grade not in GRADE_PRIORS:
        raise ValueError(f"grade {grade!r}: expected navigation or {', '.join(GRADE_PRIORS)}")
    pri = GRADE_PRIORS[grade]
    stages = []
    for st in config.stages:
        if st.kind == "kf":
            params = st.parameters or parameters_of(st.effects)
            given = dict(st.settings.get("prior_sigma", {}))
            sig = {p: pri[effect_of(p).name] for p in params if effect_of(p).name in pri and p not in given}
            st = replace(st, settings={**st.settings, "prior_sigma": {**sig, **given},
                                       "phi0": st.settings.get("phi0", GRADE_ATTITUDE[grade])})
        stages.append(st)
    return replace(config, name=f"{config.name} ({grade})", stages=stages)


def load_config(spec: str) -> Config:
    """A ready-made name, or a TOML file: [config] name, description; [[stages]] kind, name,
    effects or parameters, window, settings = {...}."""
    if spec in READY:
        return READY[spec]()
    path = Path(spec)
    if not path.exists():
        raise ValueError(f"{spec!r}: not a ready-made configuration ({', '.join(READY)}) nor a file")
    d = tomllib.loads(path.read_text())
    c = d.get("config", {})
    stages = [Stage(kind=s.get("kind", "kf"), name=s.get("name", ""), effects=s.get("effects", []),
                    parameters=s.get("parameters"), window=s.get("window"),
                    settings=dict(s.get("settings", {})), align_max_s=s.get("align_max_s", 60.0),
                    align_min_s=s.get("align_min_s", 10.0), consider_earlier=s.get("consider_earlier", False))
              for s in d.get("stages", [])]
    if not stages:
        raise ValueError(f"{path}: no [[stages]]")
    return Config(c.get("name", path.stem), c.get("description", ""), stages, c.get("schedule"))
