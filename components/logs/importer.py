"""``calbench import``: a log from the files users have (components.logs.mapping says what is
where), as a :class:`~components.logs.logfile.MeasurementLog` of format ``calbench-log/2`` (or
``/1`` when it needs nothing of version 2). Every conversion and assumption is said in the
returned notes and in the log's ``description`` and ``import`` metadata."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from components.errors import MappingError
from components.logs.angle_turns import made_continuous, said
from components.logs.clock_curve import WRONG_CLOCK_SIGMAS, bow_followed
from components.logs.logfile import MeasurementLog
from components.logs.lost_rows import leave_out_lost_rows
from components.logs.mapping import AX, Mapping
from components.logs.measurement import at_output_range
from components.logs.sample_counter import sample_index, skips
from components.logs.sources import Columns
from components.logs.stamps import imu_stamps, regular_grid, table_stamps
from components.logs.table_clock import angles_at, estimate_clock_offset, table_to_imu
from components.logs.timebase import gaps


@dataclass
class Imported:
    log: MeasurementLog
    notes: list[str] = field(default_factory=list)
    clock_offset: object = None   # table_clock.ClockOffset when estimated


def _sensor_values(cols: Columns, sensor, name: str, kind_rates: tuple) -> tuple[np.ndarray, str]:
    """(N, 3) values in the log's unit for the sensor's output kind, and that kind's log name; of
    running totals the increments, the first sample's NaN (nothing before it to count from)."""
    v = np.column_stack([cols.values(ch, f"imu.{name}.{a}") for ch, a in zip(sensor.axes, AX)])
    if sensor.accumulated:
        step = np.diff(v, axis=0)
        if sensor.rollover is not None:
            # a total's step is far below half its period: a larger one is the total rolling over
            period = sensor.rollover * np.array([abs(ch.scale) for ch in sensor.axes])
            step -= period * np.round(step / period)
        v = np.vstack([np.full((1, 3), np.nan), step])
    if sensor.output == "counts":
        if not np.all((v == np.round(v)) | np.isnan(v)):
            i, k = np.argwhere((v != np.round(v)) & ~np.isnan(v))[0]
            raise MappingError(f"{cols.where}: imu.{name}.{AX[k]}: row {i + 1}: {float(v[i, k])!r} is not a whole number of "
                               "counts (output = 'counts' means pulse counts per sample)")
        return v, "counts"
    return v * sensor.unit_si, (kind_rates[0] if sensor.output in ("rate", "specific_force") else "increment")


def import_log(m: Mapping) -> Imported:
    """The log the mapping *m* describes."""
    notes: list[str] = []
    cols = Columns(m.imu)
    lost = leave_out_lost_rows(cols, _imu_file_channels(m), notes)
    t, tick, max_int = imu_stamps(m, cols, notes)
    index = sample_index(m, cols, notes)
    skipped = skips(index)
    nominal = 1.0 / m.sample_rate_hz
    timing, fs = "nominal", m.sample_rate_hz
    # a sensor on a regular clock with rows lost: its stamps are regular but for the gaps, which
    # only measured timing has (the rates stay per the nominal interval: below)
    holed = m.timing == "nominal" and ((lost is not None and bool(lost.any()))
                                       or (skipped is not None and bool(skipped.any())))
    logged = None  # the log's time where it is not the host's (a drift, the sensor keeping time)
    bow = None  # with a drift: the host's stamps less the sensor's grid at each sample
    if m.timing == "regularise":
        reg = regular_grid(t, nominal, max_int, cols, "imu.time", index)
        t = reg.time
        notes.append(f"time stamps regularised: {reg.runs} run(s), fitted rate {reg.rate_hz:.6f} Hz "
                     f"({(reg.rate_hz / m.sample_rate_hz - 1) * 1e6:+.3g} ppm from the nominal {m.sample_rate_hz:g}), "
                     f"stamps' RMS jitter {reg.jitter_rms_s * 1e6:.3g} us")
        if reg.drift is not None:
            bow = reg.time - reg.sensor_time
            shape = ("changing steadily over the log" if reg.drift.segments == 1 else
                     f"piecewise linear between knots {reg.drift.spacing_s:.0f} s apart")
            notes.append(f"the sensor's clock drifts against the host's: its stamps bow up to {reg.drift.bow_s * 1e3:.3g} ms "
                         f"away from one regular clock, its rate moving over {reg.drift.rate_span_ppm:.3g} ppm; the samples "
                         f"follow the stamps on a smooth clock (its rate {shape})")
        if m.keeps_time == "sensor":
            # the sensor's clock keeps time: its samples are whole nominal intervals apart (the
            # grid's interval on the host's stamps is the host's rate error, 50 ppm of every
            # accelerometer scale factor on a host 50 ppm fast). They stand where the host's
            # stamps put them against a table the same host stamps, and where the sensor's own
            # clock puts them against a table controller's clock (the host's bow is then in neither)
            grid = reg.sensor_time
            logged = grid[0] + (grid - grid[0]) * (nominal * reg.rate_hz)
            notes.append(f"keeps_time = 'sensor': the log's time is the sensor's clock, {nominal * 1e3:g} ms a sample "
                         f"(the host's stamps {(1 / (nominal * reg.rate_hz) - 1) * 1e6:+.3g} ppm on it); the table's "
                         "angles " + ("are matched against it (table.time.clock = 'controller')"
                                      if m.table_clock == "controller" else "are taken at the host's stamps of its samples"))
        # how far jitter stretches one interval, at most about (a clock's tick: at most a tick)
        reach = tick or 3 * math.sqrt(2) * reg.jitter_rms_s
        if max_int - 1 / reg.rate_hz < reach and index is None:
            # a jittered interval then passes for a gap, and the runs between such gaps, chosen by
            # their long ends, fit a clock too fast, with samples a whole interval off (±0.3 ms
            # stamps of a 1 kHz sensor: one interval over the runs 90 ppm fast, each run's own
            # 2,000 ppm, as regularise did before)
            lo, hi = 1 / reg.rate_hz + reach, 2 / reg.rate_hz - reach
            notes.append(f"warning: the stamps' jitter ({reg.jitter_rms_s * 1e6:.3g} us RMS) stretches an interval by up "
                         f"to ~{reach * 1e3:.3g} ms, past imu.time.max_interval_s ({max_int * 1e3:g} ms): jitter is taken "
                         "for gaps; " + (f"give a max_interval_s between {lo * 1e3:.3g} and {hi * 1e3:.3g} ms" if hi > lo
                                         else "at this jitter no interval tells a lost sample from a late stamp")
                         + " (a sample counter in the file tells: give [imu.counter])")
        if reg.runs > 1:
            timing = "measured"
        # the sensor's rates are per its own nominal interval: the fitted rate (the host's view of
        # the sensor's clock) only places the samples in time
    elif m.timing == "measured":
        timing = "measured"
        d = np.diff(t)
        notes.append(f"measured timing: intervals {d.min() * 1e3:.4g}-{d.max() * 1e3:.4g} ms, RMS deviation from "
                     f"{nominal * 1e3:g} ms {np.sqrt(np.mean((d - nominal) ** 2)) * 1e6:.3g} us")
    elif holed:
        timing = "measured"
        notes.append("nominal timing with lost samples (lost rows, the counter skipping): the log's timing is measured "
                     "(the stamps say where the gaps are), the rates increments over the nominal "
                     f"{nominal * 1e3:g} ms as on a nominal clock")
    # the samples after a gap: left out of the log and of the clock offset's match
    after_gap = gaps(t, max_int) if timing == "measured" else np.zeros(len(t), bool)
    if skipped is not None:
        _skips_are_gaps(skipped, after_gap, t, max_int, cols)
    n_gaps = int(after_gap.sum())
    if n_gaps:
        notes.append(f"{n_gaps} gap(s) longer than {max_int * 1e3:g} ms: the sample after each is left out")
    gyro, gkind = _sensor_values(cols, m.gyro, "gyro", ("rate",))
    acc, akind = _sensor_values(cols, m.acc, "acc", ("specific_force",))
    notes.append(f"gyro: {_conversion(m.gyro, gkind, 'rad')}; accelerometer: {_conversion(m.acc, akind, 'm/s')}")
    temp = None
    if m.temperature is not None:
        temp = _temperature(m, cols, t, notes)
        temp = {"degC": temp, "K": temp - 273.15, "degF": (temp - 32.0) * 5.0 / 9.0}[m.temperature_unit]
        if m.temperature_unit != "degC":
            notes.append(f"temperature: {m.temperature_unit} converted to degC")
    seg = _labels(m, cols, t)
    _check_label_keys(m, seg)
    clock: dict = {}
    matched = logged if logged is not None and m.table_clock == "controller" else t
    whole = ~after_gap
    whole[0] &= not (m.gyro.accumulated or m.acc.accumulated)  # a running total's first increment: unknown
    gimbal, command, names, vectors, keep = _table(m, cols, matched, np.nan_to_num(gyro), gkind, notes, clock, whole)
    if bow is not None and clock.get("estimate") is not None and clock["estimate"].stretches is not None:
        wrong = _wrong_clock(clock["estimate"], matched, bow, reg.drift.bow_s, matched is logged)
        if wrong:
            notes.append(wrong)
    if logged is not None:
        t = logged
    if m.gyro.accumulated or m.acc.accumulated:
        keep, gimbal, command = _first_total_left_out(keep, len(t), gimbal, command, notes)
    if holed:
        # per the nominal interval, as a nominal log's reader takes them (measured timing would
        # take each over its stamps' interval, which nominal timing lets differ by up to 1 %)
        if gkind == "rate":
            gyro, gkind = gyro * nominal, "increment"
        if akind == "specific_force":
            acc, akind = acc * nominal, "increment"
    if keep is not None:
        t, gyro, acc = t[keep], gyro[keep], acc[keep]
        temp = None if temp is None else temp[keep]
        seg = None if seg is None else seg[keep]
    log = MeasurementLog(
        time=t, gimbal=gimbal, command=command, gyro=gyro, acc=acc, axis_names=names,
        axis_vectors=np.array(vectors, float).reshape(-1, 3), sample_rate_hz=fs, gyro_output=gkind,
        acc_output=akind, gyro_count_rad=m.gyro.count_weight, acc_count_mps=m.acc.count_weight,
        latitude_deg=m.site["latitude_deg"], height_m=m.site["height_m"], gravity_mps2=m.site["gravity_mps2"],
        description=describe(m, notes),
        temperature=temp, segment=seg, timing=timing,
        max_interval_s=m.max_interval_s if timing == "measured" and m.max_interval_s is not None else None,
        segments=m.segments, exclude=list(m.exclude),
        encoder_resolution=None if m.encoder_resolution is None or not names else
        ("exact" if m.encoder_resolution == "exact" else np.full(len(names), float(m.encoder_resolution))),
        gyro_range=None if m.gyro.full_scale is None else np.array(m.gyro.full_scale),
        acc_range=None if m.acc.full_scale is None else np.array(m.acc.full_scale))
    log.extra_metadata = {"import": {"mapping": m.where, "notes": notes}}
    log.validate(f"the log imported by {m.where}")
    return Imported(log, notes, clock.get("estimate"))


def _skips_are_gaps(skipped: np.ndarray, after_gap: np.ndarray, t: np.ndarray, max_int: float, cols: Columns) -> None:
    """Where the sample counter skips, the log's time must show a gap (the log carries lost
    samples as gaps: the sample after one is left out); stamps taken as the samples' times that
    do not (a host's late stamp before, an early one after) are one error naming the row."""
    hidden = skipped & ~after_gap
    if hidden.any():
        i = int(np.argmax(hidden))
        raise MappingError(f"{cols.where}: imu.counter.column: row {cols.file_row(i)}: the counter skips samples, but "
                           f"the stamps are {(t[i] - t[i - 1]) * 1e3:.4g} ms apart, within imu.time.max_interval_s "
                           f"({max_int * 1e3:g} ms): stamps that hide lost samples are not the samples' times; give "
                           "imu.time.timing = 'regularise' (the samples placed by the counter)")


def _imu_file_channels(m: Mapping) -> list:
    """(channel, mapping key) of the number columns of the IMU's file whose empty cell makes its
    row a lost packet: not the temperature, whose empty cells are more likely a temperature read
    less often than the samples (imu.temperature.sparse; without it such a cell is an error)."""
    out = [(m.time, "imu.time.column")] + ([(m.counter, "imu.counter.column")] if m.counter is not None else [])
    out += [(ch, f"imu.{name}.{a}") for name, sensor in (("gyro", m.gyro), ("acc", m.acc))
            for ch, a in zip(sensor.axes, AX)]
    return out + (_axis_channels(m) if m.table is None else [])


def _table_file_channels(m: Mapping) -> list:
    """(channel, mapping key) of every number column the import reads from the table's file."""
    return [(m.table_time, "table.time.column")] + _axis_channels(m)


def _axis_channels(m: Mapping) -> list:
    """(channel, mapping key) of the table's angle and command columns, in whichever file they are."""
    return ([(a.channel, f"table.axes.{a.name}") for a in m.axes]
            + [(a.command, f"table.axes.{a.name}.command") for a in m.axes if a.command is not None])


def _first_total_left_out(keep, n: int, gimbal: dict, command: dict, notes: list[str]):
    """Running totals: the first sample's increment is not known. (*keep*, or all *n* samples,
    without it; the table's angles and commands, which are of the kept samples, without theirs.)"""
    keep = np.ones(n, bool) if keep is None else keep.copy()
    if keep[0]:
        gimbal = {k: v[1:] for k, v in gimbal.items()}
        command = {k: v[1:] for k, v in command.items()}
    keep[0] = False
    notes.append("running totals (accumulated): the first sample's increment is not known and it is left out")
    return keep, gimbal, command


def _conversion(sensor, kind: str, si: str) -> str:
    """What the import did to a sensor's values: its unit (or count weight) and each axis's column,
    with a reversed sign and an ADC map said."""
    if kind == "counts":
        what = f"{sensor.output} of {sensor.count_weight:g} {si}"
    else:
        what = f"{sensor.output} in {sensor.unit} (x {sensor.unit_si:.6g} to SI)"
    cols = []
    for a, ch in zip(AX, sensor.axes):
        c = f"{a} = {'-' if ch.sign < 0 else ''}{ch.column}"
        if ch.scale != 1.0 or ch.offset != 0.0:
            c += f" (raw - {ch.offset:g}) x {ch.scale:g}"
        cols.append(c)
    reversed_ = [a for a, ch in zip(AX, sensor.axes) if ch.sign < 0]
    return f"{what}; {', '.join(cols)}" + (f" (sign reversed: {', '.join(reversed_)})" if reversed_ else "")


SHOWN_LABELS = 60  # the data's labels an error lists, to find the intended one


def _temperature(m: Mapping, cols: Columns, t: np.ndarray, notes: list[str]) -> np.ndarray:
    """The temperature column at every sample; read less often than the samples
    (imu.temperature.sparse), linear in time between its readings and held before the first and
    after the last (a temperature moves by far less than its resolution in one reading's time)."""
    try:
        temp = cols.values(m.temperature, "imu.temperature.column", empty=m.temperature_sparse)
    except MappingError as e:
        if "empty value" in str(e) and not m.temperature_sparse:
            raise MappingError(f"{e} (a temperature read less often than the samples, empty between its readings: "
                               "give imu.temperature.sparse = true)") from None
        raise
    if not m.temperature_sparse:
        return temp
    read = np.flatnonzero(np.isfinite(temp))
    if not len(read):
        raise MappingError(f"{cols.where}: imu.temperature.column: no reading in any row; expected a temperature in "
                           "some rows (imu.temperature.sparse)")
    notes.append(f"temperature: {len(read)} reading(s) in {len(t)} samples (imu.temperature.sparse), linear in time "
                 f"between them, held before the first and after the last")
    return np.interp(t, t[read], temp[read])


def _check_label_keys(m: Mapping, seg) -> None:
    """The labels the mapping's 'segments' and 'exclude' name against those the data carry: a typo
    would otherwise fail (or silently drop a position) in every command after the import."""
    have = set() if seg is None else set(map(str, seg))
    for key, names in (("segments", [lab for lab, d in (m.segments or {}).items()
                                     if not (isinstance(d, dict) and d.get("kind") == "excluded")]),
                       ("exclude", [x for x in m.exclude if isinstance(x, str)])):
        missing = [lab for lab in names if lab not in have]
        if missing:
            shown = sorted(have)[:SHOWN_LABELS]
            more = f" and {len(have) - len(shown)} more" if len(have) > len(shown) else ""
            raise MappingError(f"{m.where}: key '{key}' names label(s) {', '.join(map(repr, missing))} that no sample "
                               f"carries; expected labels of the data ({', '.join(shown) or 'none'}{more})")


def describe(m: Mapping, notes: list[str]) -> str:
    """The imported log's description: the mapping's, and what the import did."""
    return ((m.description + "\n" if m.description else "") + "imported by calbench import from " + m.imu.path.name
            + (f" and {m.table.path.name}" if m.table is not None else "") + ": " + "; ".join(notes))


def _labels(m: Mapping, cols: Columns, t: np.ndarray):
    if m.labels is not None:
        lab = cols.text(m.labels, "labels.column")
        empty = np.asarray(lab == "", bool)
        if empty.any():
            raise MappingError(f"{cols.where}: labels.column: row {int(np.argmax(empty)) + 1}: empty label")
        return lab
    if m.label_ranges:
        lab = np.full(len(t), "unlabelled", dtype=object)
        for t0, t1, name in m.label_ranges:
            lab[(t >= t0) & (t <= t1)] = name
        return lab
    return None


def _continuous(cols: Columns, axes: list, notes: list[str]) -> list[np.ndarray]:
    """The *axes*' angle readings [rad], made continuous where a controller read them to one
    turn (components.logs.angle_turns; one note names the axes), before anything interpolates
    them or takes their steps as the table's travel."""
    out, mended = [], {}
    for axis in axes:
        angle, mended[axis.name] = made_continuous(cols.values(axis.channel, f"table.axes.{axis.name}") * axis.unit_si)
        out.append(angle)
    line = said(mended)
    if line:
        notes.append(f"{cols.where}: {line}")
    return out


def _counted(m: Mapping, angle: np.ndarray, notes: list[str]) -> np.ndarray:
    """*angle* [rad] rounded to whole counts of the encoder when the mapping asks for it: a rest
    then reads one count (two where its noise crosses a count's edge) instead of a new value at
    every sample, which no rest survives."""
    if not m.round_to_count:
        return angle
    q = float(m.encoder_resolution)
    note = f"table angles rounded to whole counts of {np.degrees(q) * 3600:.4g}\" (round_to_count)"
    if note not in notes:
        notes.append(note)
    return np.round(angle / q) * q


def _wrong_clock(co, matched: np.ndarray, bow: np.ndarray, bow_s: float, against_sensor: bool) -> str | None:
    """A warning where a table on a clock of its own keeps the other clock's time than the mapping
    says (clock_curve.bow_followed), else None."""
    got = bow_followed(co.stretches, matched, bow)
    if got is None:
        return None
    a, sa = got
    other = -1.0 if against_sensor else 1.0  # where its offsets stand if the other clock drifts
    if abs(a) < WRONG_CLOCK_SIGMAS * sa or abs(a - other) >= abs(a):
        return None
    said = (f"its offsets from the log's time follow {a:+.2f} ± {sa:.2g} of the host stamps' bow "
            f"(up to {bow_s * 1e3:.3g} ms; {other:+.0f} where it keeps the other clock's time, 0 where it keeps the log's)")
    if against_sensor:
        return ("warning: the table's clock keeps the host's time, not the sensor's: " + said + ": the sensor's clock "
                "is the one that drifts (imu.time.keeps_time = 'host'), or the host stamps the table file "
                "(table.time.clock = 'host')")
    return ("warning: the table's clock keeps the sensor's time, not the host's: " + said + ", as where the host's "
            "clock drifts against a sensor and a table controller that keep time: give imu.time.keeps_time = 'sensor' "
            "and table.time.clock = 'controller'")


def _table(m: Mapping, cols: Columns, t, gyro, gkind, notes, clock: dict, whole: np.ndarray):
    """(gimbal, command, axis names, axis vectors, samples kept) from the IMU file's own columns
    or a separate table file on its own clock (its offset from the *whole* samples: those not
    after a gap)."""
    if not m.axes:
        return {}, {}, [], [], None
    names = [a.name for a in m.axes]
    vectors = [a.vector for a in m.axes]
    if m.table is None:
        gimbal = {a.name: _counted(m, x, notes) for a, x in zip(m.axes, _continuous(cols, m.axes, notes))}
        command = {a.name: cols.values(a.command, f"table.axes.{a.name}.command") * a.unit_si
                   for a in m.axes if a.command is not None}
        return gimbal, command, names, vectors, None
    tc = Columns(m.table)
    leave_out_lost_rows(tc, _table_file_channels(m), notes)
    tt = table_stamps(m, tc, notes)
    ang = np.column_stack([_counted(m, x, notes) for x in _continuous(tc, m.axes, notes)])
    cmd = {a.name: tc.values(a.command, f"table.axes.{a.name}.command") * a.unit_si for a in m.axes
           if a.command is not None}
    if m.clock_offset == "estimate":
        dt = np.concatenate([[np.median(np.diff(t))], np.diff(t)])
        if gkind == "counts":
            inc = gyro * m.gyro.count_weight
        elif m.gyro.output == "rate":
            inc = gyro * dt[:, None]
        else:
            inc = gyro
        if m.gyro.full_scale is not None:
            # a clipped increment is not the table's turn: the samples at the gyros' range left out
            whole = whole & ~at_output_range(np.abs(inc) / dt[:, None], np.array(m.gyro.full_scale))
        co = estimate_clock_offset(t, dt, inc, tt, ang, np.array(vectors), use=whole)
        clock["estimate"] = co
        offset, rate, curve = co.offset_s, co.rate, co.curve
        drift = (f"; the IMU's clock {co.rate * 1e6:+.4g} ± {co.rate_sigma * 1e6:.2g} ppm against the table's: "
                 f"{abs(co.rate) * (tt[-1] - tt[0]) * 1e3:.3g} ms over the record" if co.rate else "")
        drift += f"; {co.curve.said()}" if co.curve is not None else ""
        notes.append(f"clock offset table -> IMU estimated {co.offset_s * 1e3:+.4f} ± {co.sigma_s * 1e3:.2g} ms at the "
                     f"table's first sample{drift} (each half on its own: {co.first_half_s * 1e3:+.4f}, "
                     f"{co.second_half_s * 1e3:+.4f} ms at its middle; the gyros' and the table's turns over its intervals correlate {co.correlation:.4f})")
    else:
        offset, rate, curve = float(m.clock_offset or 0.0), m.clock_rate, m.clock_curve
        notes.append(f"clock offset table -> IMU {offset * 1e3:+.4f} ms (given)"
                     + (f", the IMU's clock {rate * 1e6:+.4g} ppm against the table's (given)" if rate else ""))
    ti = table_to_imu(tt, offset, rate, curve)
    keep = (t >= ti[0]) & (t <= ti[-1])
    if not keep.any():
        raise MappingError(f"{tc.where}: the table record ({ti[0]:.6g}-{ti[-1]:.6g} s on the IMU clock) does not "
                           f"overlap the IMU's ({t[0]:.6g}-{t[-1]:.6g} s)")
    if not keep.all():
        notes.append(f"{int((~keep).sum())} IMU sample(s) outside the table record dropped")
    at = angles_at(t[keep], ti, ang)
    gimbal = {n: at[:, k] for k, n in enumerate(names)}
    command = {n: angles_at(t[keep], ti, cmd[n][:, None])[:, 0] for n in cmd}
    notes.append(f"table angles from {tc.source.path.name} ({len(tt)} samples, {1 / np.median(np.diff(tt)):.4g} Hz) "
                 "interpolated to the IMU's times (PCHIP; a rest's reading held exactly)")
    return gimbal, command, names, vectors, keep
