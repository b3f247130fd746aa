"""Variable table of the IMU FMU (role ``imu``): the single source of its modelDescription.xml
and C value references. Effect parameters follow the vocabulary of architecture.md §5
(``<sensor>.<effect>.<index>``), SI units, all zero by default."""
from __future__ import annotations

from fmus.modeldef import ModelTable, integer, real

AX = "xyz"
OFF_DIAG = ("xy", "xz", "yx", "yz", "zx", "zy")
PAIRS = ("xx", "yy", "zz", "xy", "xz", "yz")  # symmetric products f_j f_k for g^2-sensitivity


def _vec(prefix: str, unit: str, what: str) -> list:
    return [real(f"{prefix}.{c}", "parameter", 0.0, unit, f"{what}, {c} axis") for c in AX]


# (effect name, [(parameter suffix, unit, description)])
def _effect_parameters() -> list:
    v = []
    v += _vec("gyro.bias", "rad/s", "gyro bias")
    v += _vec("gyro.sf", "1", "gyro scale-factor error")
    v += _vec("gyro.sf_asym", "1", "gyro scale-factor asymmetry (term s * w_i * sign(w_i))")
    v += [real(f"gyro.mis.{ij}", "parameter", 0.0, "1",
               f"gyro misalignment: sensitivity of axis {ij[0]} to rate on axis {ij[1]}")
          for ij in OFF_DIAG]
    v += [real(f"gyro.gsens.{i}{j}", "parameter", 0.0, "rad.s/m",
               f"gyro g-sensitivity: axis {i} per specific force on axis {j}")
          for i in AX for j in AX]
    v += [real(f"gyro.g2sens.{i}.{jk}", "parameter", 0.0, "rad.s3/m2",
               f"gyro g^2-sensitivity: axis {i} per f_{jk[0]} f_{jk[1]}")
          for i in AX for jk in PAIRS]
    v += _vec("gyro.temp", "rad/s/K", "gyro bias change per kelvin from temperature.ref")
    v += _vec("gyro.sf_temp", "1/K", "gyro scale-factor change per kelvin")
    v += _vec("gyro.drift", "rad/s/s", "gyro linear bias drift per second")
    v += _vec("acc.bias", "m/s2", "accelerometer bias")
    v += _vec("acc.sf", "1", "accelerometer scale-factor error")
    v += _vec("acc.sf_asym", "1", "accelerometer scale-factor asymmetry (s * f_i * sign(f_i))")
    v += [real(f"acc.mis.{ij}", "parameter", 0.0, "1",
               f"accelerometer misalignment: sensitivity of axis {ij[0]} to force on axis {ij[1]}")
          for ij in OFF_DIAG]
    v += _vec("acc.k2", "s2/m", "accelerometer second-order nonlinearity (k2 * f_i^2)")
    v += _vec("acc.k3", "s4/m2", "accelerometer third-order nonlinearity (k3 * f_i^3)")
    v += [real(f"acc.cross.{ij}", "parameter", 0.0, "s2/m",
               f"accelerometer cross-coupling: axis {ij[0]} per f_{ij[0]} f_{ij[1]}")
          for ij in OFF_DIAG]
    v += [real(f"acc.lever.{i}.{k}", "parameter", 0.0, "m",
               f"size effect: {k} component of the {i} accelerometer's offset from the plate point")
          for i in AX for k in AX]
    v += _vec("acc.temp", "m/s2/K", "accelerometer bias change per kelvin from temperature.ref")
    v += _vec("acc.sf_temp", "1/K", "accelerometer scale-factor change per kelvin")
    v += _vec("acc.drift", "m/s2/s", "accelerometer linear bias drift per second")
    v.append(real("imu.time_offset", "parameter", 0.0, "s",
                  "IMU sample time late relative to the table: the sample labelled t holds the "
                  "motion of (t - h + dt, t + dt]"))
    v.append(real("acc.time_offset", "parameter", 0.0, "s",
                  "accelerometer samples late relative to the gyros (gyro-accelerometer asynchrony): "
                  "the accelerometer sample labelled t holds the motion of (t - h + dt + dta, t + dt + dta]"))
    return v


def _noise_parameters() -> list:
    return [
        real("gyro.noise.arw", "parameter", 0.0, "rad/sqrt(s)", "angle random walk (white rate noise density)"),
        real("gyro.noise.bi", "parameter", 0.0, "rad/s",
             "bias instability B (Allan floor 0.664 B), as one Gauss-Markov process or, with "
             "bi_tau_max, a sum of them"),
        real("gyro.noise.bi_tau", "parameter", 100.0, "s",
             "correlation time of that process; with bi_tau_max, the low end of the flicker range"),
        real("gyro.noise.bi_tau_max", "parameter", 0.0, "s",
             "flicker bias instability: when > bi_tau, the bias instability is a sum of Gauss-Markov "
             "terms whose Allan deviation stays near 0.664 B from bi_tau to bi_tau_max (noise.c); "
             "<= bi_tau: the single Gauss-Markov process"),
        real("gyro.noise.rrw", "parameter", 0.0, "rad/s/sqrt(s)", "rate random walk"),
        real("acc.noise.vrw", "parameter", 0.0, "m/s/sqrt(s)", "velocity random walk (white noise density)"),
        real("acc.noise.bi", "parameter", 0.0, "m/s2",
             "bias instability B (Allan floor 0.664 B), as one Gauss-Markov process or, with "
             "bi_tau_max, a sum of them"),
        real("acc.noise.bi_tau", "parameter", 100.0, "s",
             "correlation time of that process; with bi_tau_max, the low end of the flicker range"),
        real("acc.noise.bi_tau_max", "parameter", 0.0, "s",
             "flicker bias instability: when > bi_tau, the bias instability is a sum of Gauss-Markov "
             "terms whose Allan deviation stays near 0.664 B from bi_tau to bi_tau_max (noise.c); "
             "<= bi_tau: the single Gauss-Markov process"),
        real("acc.noise.rrw", "parameter", 0.0, "m/s2/sqrt(s)", "acceleration random walk"),
        integer("seed", "parameter", 1, "seed of this instance's noise generator"),
    ]


VARIABLES = _effect_parameters() + _noise_parameters() + [
    integer("gyro.output", "parameter", 0, "gyro output kind: 0 increment [rad], 1 rate [rad/s], 2 counts"),
    integer("acc.output", "parameter", 0, "accelerometer output kind: 0 increment [m/s], 1 specific force [m/s2], 2 counts"),
    real("gyro.count_weight", "parameter", 1e-6, "rad", "angle of one gyro count"),
    real("acc.count_weight", "parameter", 1e-5, "m/s", "velocity of one accelerometer count"),
    integer("input_timing", "parameter", 0,
            "0: inputs set before doStep(t, h) are the values at t + h (the IMU runs after its "
            "motion source, Gauss-Seidel) and are interpolated (cubic Hermite, alpha as the "
            "derivative of omega) against the previous ones; 1: they are the values at t (FMI "
            "default) and are extrapolated with alpha and any input derivatives"),
    integer("input_integrals", "parameter", 0,
            "0: ignore omega_int / f_int; 1: they are the integrals of omega and f over the "
            "interval that ends at the knot being set (the communication step just ended), and "
            "the interpolant between two knots is the quartic that also matches that integral "
            "(exact increments for every effect linear in the motion)"),
    integer("temperature.mode", "parameter", 0, "0 constant, 1 ramp, 2 from input temperature_env"),
    real("temperature.start", "parameter", 25.0, "degC", "IMU temperature at start (modes 0, 1)"),
    real("temperature.rate", "parameter", 0.0, "K/s", "temperature ramp rate (mode 1)"),
    real("temperature.ref", "parameter", 25.0, "degC", "reference temperature T0 of the coefficients"),
]
VARIABLES += [real(f"omega.{c}", "input", 0.0, "rad/s", f"inertial angular rate at the mount, {c} axis")
              for c in AX]
VARIABLES += [real(f"f.{c}", "input", 0.0, "m/s2", f"specific force at the mounting point, {c} axis")
              for c in AX]
VARIABLES += [real(f"alpha.{c}", "input", 0.0, "rad/s2", f"angular acceleration (d omega/dt), {c} axis")
              for c in AX]
VARIABLES += [real(f"omega_int.{c}", "input", 0.0, "rad",
                   f"integral of omega.{c} over the interval ending at this knot (input_integrals 1)")
              for c in AX]
VARIABLES += [real(f"f_int.{c}", "input", 0.0, "m/s",
                   f"integral of f.{c} over the interval ending at this knot (input_integrals 1)")
              for c in AX]
VARIABLES.append(real("temperature_env", "input", 25.0, "degC", "environment temperature (mode 2)"))
# No unit is declared on the sensor outputs: it follows the output kind chosen by gyro.output /
# acc.output (rad, rad/s or counts; m/s, m/s2 or counts), which the role binding states.
VARIABLES += [real(f"gyro.{c}", "output", None, None,
                   f"gyro output over the interval just ended, {c} axis: increment [rad], "
                   "mean rate [rad/s] or counts, per gyro.output")
              for c in AX]
VARIABLES += [real(f"acc.{c}", "output", None, None,
                   f"accelerometer output over the interval just ended, {c} axis: increment [m/s], "
                   "mean specific force [m/s2] or counts, per acc.output")
              for c in AX]
VARIABLES.append(real("temperature", "output", None, "degC", "IMU temperature"))

TABLE = ModelTable(
    identifier="calbench_imu",
    description="calbench strapdown IMU: gyro and accelerometer triads with error effects and noise",
    variables=VARIABLES,
    sources=["model.c", "signal.c", "noise.c"],
    default_step=0.005,
)
