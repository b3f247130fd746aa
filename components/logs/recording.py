"""A ``calbench-log/1`` measurement log from an orchestrator recording of a turntable + IMU
run (the writer of simulated logs)."""
from __future__ import annotations

import math

import numpy as np

from components.logs.labels import SegmentLabels
from components.logs.logfile import MeasurementLog
from components.logs.rules import FORMAT, XYZ, parse_metadata

# ---------------------------------------------------------------------------- from a run
_KIND_CODES = {"gyro": {0: "increment", 1: "rate", 2: "counts"},
               "acc": {0: "increment", 1: "specific_force", 2: "counts"}}


def log_from_recording(recording, metadata: dict | None = None, table: str = "table", imu: str = "imu",
                       axes: list[str] | None = None, gyro_output: str | None = None,
                       acc_output: str | None = None, segment_signal: str | None = None,
                       segment_labels=None, description: str | None = None) -> MeasurementLog:
    """A :class:`MeasurementLog` from a recorded turntable + IMU run.

    Signals used: ``<table>.<axis>.angle`` (required per axis), ``<table>.<axis>.angle_cmd``
    (commands, if recorded), ``<imu>.gyro.x/y/z`` and ``<imu>.acc.x/y/z`` (required),
    ``<imu>.temperature`` (if recorded), ``segment_signal`` (a recorded numeric signal; its
    values become labels through ``segment_labels``: a dict or list by value, or a callable;
    default ``str(int(v))``). The first recorded row (the start time, before any interval) is
    dropped: a log sample is the output over the interval ending at its time.

    ``metadata`` is a partial ``calbench-log/1`` metadata dict (site, table.axes, imu kinds and
    count weights, description); what it does not give comes from the run's provenance (the
    parameters of the table and IMU units: ``site.latitude`` [rad], ``site.height``,
    ``site.gravity`` (0 = normal), ``<axis>.axis.x/y/z``, ``gyro.output``/``acc.output`` codes and
    count weights), then from the builtin FMUs' defaults. The recording must hold every IMU
    sample: the recording interval must equal the IMU unit's step.
    """
    metadata = dict(metadata or {})
    prov = recording.provenance or {}
    sysp = prov.get("system", {})
    units = prov.get("units", {})
    tpar = units.get(table, {}).get("parameters", {}) or {}
    ipar = units.get(imu, {}).get("parameters", {}) or {}
    t_all = np.asarray(recording.t, dtype=float)
    if len(t_all) < 2:
        raise ValueError("the recording has fewer than two rows: no IMU sample interval")
    if "step" in sysp:
        rec_dt = sysp["step"] * sysp.get("record_every", 1)
        imu_dt = sysp["step"] * units.get(imu, {}).get("step_multiple", 1)
        if abs(rec_dt - imu_dt) > 1e-12 * imu_dt:
            raise ValueError(f"recording interval {rec_dt} s differs from the IMU unit's step {imu_dt} s: the rows "
                             "would not be one IMU sample each (set record.every to the IMU's step_multiple)")
        fs = 1.0 / imu_dt
    else:
        fs = 1.0 / float(np.median(np.diff(t_all)))

    site = dict(metadata.get("site", {}))
    from fmus.turntable.variables import DEFAULT_AXIS

    site.setdefault("latitude_deg", math.degrees(float(tpar.get("site.latitude", math.radians(39.9)))))
    site.setdefault("height_m", float(tpar.get("site.height", 50.0)))
    if "gravity_mps2" not in site:
        g = float(tpar.get("site.gravity", 0.0))
        site["gravity_mps2"] = g if g > 0 else None
    if "table" in metadata and "axes" in metadata["table"]:
        table_axes = metadata["table"]["axes"]
    else:
        names = axes or [a for a in ("outer", "middle", "inner") if f"{table}.{a}.angle" in recording.signals]
        table_axes = [{"name": a, "axis": [float(tpar.get(f"{a}.axis.{c}", DEFAULT_AXIS.get(a, (0, 0, 1))[k]))
                                           for k, c in enumerate(XYZ)]} for a in names]
    imu_meta = dict(metadata.get("imu", {}))
    for sensor, kw, wkey, wpar, wdef in (("gyro", gyro_output, "gyro_count_rad", "gyro.count_weight", 1e-6),
                                         ("acc", acc_output, "acc_count_mps", "acc.count_weight", 1e-5)):
        if kw is not None:
            imu_meta[f"{sensor}_output"] = kw
        imu_meta.setdefault(f"{sensor}_output", _KIND_CODES[sensor].get(int(ipar.get(f"{sensor}.output", 0)), "?"))
        if imu_meta[f"{sensor}_output"] == "counts":
            imu_meta.setdefault(wkey, float(ipar.get(wpar, wdef)))
        else:
            imu_meta.setdefault(wkey, None)
    imu_meta["sample_rate_hz"] = fs
    meta = {"format": FORMAT, "site": site, "table": {"axes": table_axes}, "imu": imu_meta,
            "description": description if description is not None else metadata.get(
                "description", f"simulated run of {sysp.get('name', 'a system')}")}
    parsed = parse_metadata(meta, "log_from_recording metadata")

    def sig(name: str) -> np.ndarray:
        return np.asarray(recording[name], dtype=float)[1:]

    axis_names = parsed["axis_names"]
    gimbal = {a: sig(f"{table}.{a}.angle") for a in axis_names}
    command = {a: sig(f"{table}.{a}.angle_cmd") for a in axis_names if f"{table}.{a}.angle_cmd" in recording.signals}
    seg = None
    if segment_signal is not None:
        vals = sig(segment_signal)
        if callable(segment_labels):
            f = segment_labels
        elif segment_labels is not None:
            f = lambda v: segment_labels[int(v)]  # noqa: E731
        else:
            f = lambda v: str(int(v))  # noqa: E731
        uniq, inv = np.unique(vals, return_inverse=True)
        names = [f(v) for v in uniq]
        # as runs; labels that are not text are refused by the log, naming a sample
        seg = SegmentLabels.from_codes(inv.ravel(), names) if all(isinstance(x, str) for x in names) \
            else np.array(names, dtype=object)[inv]
    log = MeasurementLog(
        time=t_all[1:].copy(), gimbal=gimbal, command=command,
        gyro=np.column_stack([sig(f"{imu}.gyro.{c}") for c in XYZ]),
        acc=np.column_stack([sig(f"{imu}.acc.{c}") for c in XYZ]),
        temperature=sig(f"{imu}.temperature") if f"{imu}.temperature" in recording.signals else None,
        segment=seg,
        **{k: parsed[k] for k in ("axis_names", "axis_vectors", "sample_rate_hz", "gyro_output", "acc_output",
                                  "gyro_count_rad", "acc_count_mps", "latitude_deg", "height_m", "gravity_mps2",
                                  "description", "extra_metadata")},
    )
    log.validate("log_from_recording")
    return log

