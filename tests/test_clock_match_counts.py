"""The clock match on coarse gyro pulse counts (components.logs.table_clock): a table on the IMU's
clock, its angles exact, the gyros counting pulses of 2″ (a ring-laser gyro's). Each sample's
running count is the turn rounded down to a pulse, an error of up to one pulse that is the same
whatever shift is tried; interpolated at the table's readings it is smaller between the IMU's
samples than at them (a cubic's weights), so a least squares on the turns alone leans towards
readings half a sample off, most where the table turns at a constant rate and nothing else
pins the shift. Checked against the truth the record is made with."""
import numpy as np

from components.logs.table_clock import estimate_clock_offset

DT = 0.005          # IMU and table both at 200 Hz
PULSE = 1e-5        # rad: 2 arcsec
OFFSET = 2.7e-3     # the table's readings 0.54 of a sample off the IMU's
FINE = 1e-4         # the motion's integration step


def _motion():
    """(fine times, angle [rad]): moves of 90° with raised-cosine rate ramps of 1 s at 20°/s, rests
    of 4 s between, then a turn at 10°/s for 4 minutes (a rotation test's)."""
    segments = []  # (duration, rate at its start, rate at its end): raised-cosine between
    peak, rotation = np.radians(20.0), np.radians(10.0)
    for k in range(16):
        sign = 1 if k % 2 == 0 else -1
        cruise = np.radians(90.0) / peak - 1.0  # the ramps turn one second's worth together
        segments += [(4.0, 0, 0), (1.0, 0, sign * peak), (cruise, sign * peak, sign * peak), (1.0, sign * peak, 0)]
    segments += [(4.0, 0, 0), (2.0, 0, rotation), (240.0, rotation, rotation), (2.0, rotation, 0), (4.0, 0, 0)]
    pieces = []
    for duration, a, b in segments:
        x = np.arange(0.0, duration, FINE) / duration
        pieces.append(a + (b - a) * 0.5 * (1 - np.cos(np.pi * x)))
    rate = np.concatenate(pieces)
    t = np.arange(len(rate)) * FINE
    return t, np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * FINE)])


def _records(seed: int):
    t, angle = _motion()
    rng = np.random.default_rng(seed)
    t_imu = np.arange(1.0, t[-1] - 1.0, DT)
    nodes = np.concatenate([[t_imu[0] - DT], t_imu])
    # the sensor's pulse count at each sample's end: the turn since power-on (an arbitrary start
    # within a pulse) rounded down to a whole pulse
    counts = np.floor((np.interp(nodes, t, angle) + rng.uniform(0, PULSE)) / PULSE)
    gyro = np.zeros((len(t_imu), 3))
    gyro[:, 2] = np.diff(counts) * PULSE
    t_tab = np.arange(t_imu[0] - 0.5, t_imu[-1] + 0.5, DT) + rng.uniform(0, DT)
    angles = np.interp(t_tab + OFFSET, t, angle)[:, None]  # table time + offset = IMU time
    return t_imu, np.full(len(t_imu), DT), gyro, t_tab, angles


def test_coarse_pulse_counts_leave_the_offset_where_the_motion_puts_it():
    """Over five draws of where the count stands within a pulse and of the readings' phase: the
    offset within 3 of its σ and the σ under 50 µs, a hundredth of a sample (the least squares on
    the turns alone: up to 1.4 ms towards half a sample, 7 of its σ), no rate between the clocks
    said and no curve (on the foreign rig's such counts it followed a bow of 8 ms)."""
    z = []
    for seed in range(5):
        co = estimate_clock_offset(*_records(seed), np.array([[0.0, 0.0, 1.0]]))
        assert co.curve is None and co.rate == 0.0, (seed, co)
        assert co.sigma_s < 50e-6, (seed, co.sigma_s)
        z.append((co.offset_s - OFFSET) / co.sigma_s)
    assert np.max(np.abs(z)) < 3.0, z
