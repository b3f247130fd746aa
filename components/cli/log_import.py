"""``calbench import MAPPING.toml --out STEM``: the files users have (CSV/TSV, Parquet, MAT, HDF5;
any units; separate IMU and table files on their own clocks) as a calbench-log/2 pair
(docs/import.md)."""
from __future__ import annotations

import argparse
import math


def _cmd_import(args: argparse.Namespace) -> int:
    from components.logs.importer import import_log
    from components.logs.logfile import write_log
    from components.logs.mapping import load_mapping

    m = load_mapping(args.mapping)
    imp = import_log(m)
    if m.table is not None and m.clock_offset == "estimate" and imp.clock_offset is not None:
        imp = refine_clock_offset(m, imp)
    log = imp.log
    paths = write_log(args.out, log, args.format)
    print(f"imported {log.n} samples, {log.time[-1] - log.time[0] + log.dt:.6g} s at {log.sample_rate_hz:.6g} Hz "
          f"({log.timing} timing), {len(log.axis_names)} table axis(es), format {log.version}")
    for n in imp.notes:
        print(f"  {n}")
    print(f"-> {', '.join(map(str, paths))}")
    from components.cli import json_option

    json_option.record(args, samples=int(log.n), duration_s=float(log.time[-1] - log.time[0] + log.dt),
                       sample_rate_hz=float(log.sample_rate_hz), timing=log.timing, axes=list(log.axis_names),
                       format=log.version, notes=list(imp.notes), out=[str(p) for p in paths])
    return 0


def refine_clock_offset(m, imp):
    """The clock offset matched on the rates (limited by the encoder's count against the motion
    between table samples: sub-µs with a fine 1 kHz table, tens of µs with a coarse 200 Hz one)
    combined with the least squares' imu.time_offset on the merged log, which the accelerometers
    see as gravity turning through them at every move (µs), by their inverse variances; the log
    is merged again at the combined offset. What it measures is the IMU's delay against the table
    as a whole: a clock offset and a delay inside the IMU cannot be told apart from two records."""
    from components.errors import EstimationError
    from components.estimation.log_data import LogData
    from components.estimation.lsq import calibrate
    from components.logs.importer import describe, import_log
    from components.model.effects import DEFAULT_EFFECTS

    coarse, s_rate = imp.clock_offset.offset_s, imp.clock_offset.sigma_s
    # the least squares shift the whole record alike: they add to what the match knows at the
    # line's centre; where the offset is said (the table's first sample, often before the first
    # move) the rate's and the curve's extrapolation stays as uncertain as the match says
    beyond = imp.clock_offset.beyond_centre_s
    s_centre = math.sqrt(max(s_rate**2 - beyond**2, 0.0))
    offset = coarse
    try:
        for _ in range(2):
            fit = calibrate(LogData.from_log(imp.log), list(DEFAULT_EFFECTS) + ["imu.time_offset"])
            k = fit.parameters.index("imu.time_offset")
            # the IMU's samples late by τ against the merged angles: the table's clock was taken
            # τ too late
            lsq, s_lsq = offset - float(fit.value[k]), float(fit.sigma[k])
            w_rate, w_lsq = (1 / s_centre**2 if s_centre > 0 else 0.0), 1 / s_lsq**2
            offset = (coarse * w_rate + lsq * w_lsq) / (w_rate + w_lsq)
            sigma = math.hypot((w_rate + w_lsq) ** -0.5, beyond)
            m.clock_offset, m.clock_rate, m.clock_curve = offset, imp.clock_offset.rate, imp.clock_offset.curve
            again = import_log(m)
            imp = type(imp)(again.log, [n for n in imp.notes if not n.startswith("clock offset")]
                            + [n for n in again.notes if not n.startswith(("clock offset", "gyro:", "time stamps",
                                                                           "measured timing", "table angles"))
                               and n not in imp.notes], imp.clock_offset)
    except (EstimationError, ValueError) as e:
        imp.notes.append(f"clock offset not refined by the least squares ({e}); the rate-matched value stands")
        return imp
    finally:
        m.clock_offset, m.clock_rate, m.clock_curve = "estimate", 0.0, None
    rate, s_r = imp.clock_offset.rate, imp.clock_offset.rate_sigma
    imp.notes.append(f"clock offset table -> IMU {offset * 1e3:+.4f} ± {sigma * 1e3:.2g} ms"
                     + (f" at the table's first sample, the IMU's clock {rate * 1e6:+.6g} ± {s_r * 1e6:.2g} ppm against "
                        "the table's" if rate else "")
                     + (f", {imp.clock_offset.curve.said()}" if imp.clock_offset.curve is not None else "")
                     + ": matched on the rates "
                     f"{coarse * 1e3:+.4f} ± {s_rate * 1e3:.2g} ms, by the least squares' imu.time_offset on the "
                     f"merged log {lsq * 1e3:+.4f} ± {s_lsq * 1e3:.2g} ms (it includes any delay inside the IMU), "
                     "combined")
    imp.log.extra_metadata["import"]["notes"] = list(imp.notes)
    imp.log.description = describe(m, imp.notes)
    return imp


def register(sub) -> None:
    p = sub.add_parser("import", help="a log from other software (CSV/TSV, Parquet, MAT, HDF5; any units; "
                                      "separate IMU and table files) to calbench-log/2, driven by a mapping "
                                      "TOML (docs/import.md)")
    p.add_argument("mapping", help="the mapping file (TOML): which file holds what, in which unit")
    p.add_argument("--out", required=True, help="stem of the log pair to write")
    p.add_argument("--format", choices=("csv", "parquet", "both"), default="csv",
                   help="sample file format of the written log (default csv)")
    p.set_defaults(func=_cmd_import)
