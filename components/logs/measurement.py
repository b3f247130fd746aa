"""One measurement log in memory (formats ``calbench-log/1`` and ``/2``, docs/measurement-log.md):
its samples as in the file, its metadata, and what follows from them — increments in SI, each
sample's interval, gaps, what is left out and why. components.logs.logfile reads and writes it.

* **Increments.** ``rate`` and ``specific_force`` outputs are means over the sample interval,
  converted to increments with the nominal interval ``1 / sample_rate_hz``; with measured timing
  (version 2) with each sample's own interval, the first sample's being the nominal one.
* **What is left out** (version 2): :meth:`MeasurementLog.usable` is False for the sample after
  a gap (its interval's start is unknown), for ``mask`` = 0, inside an ``exclude`` time range
  (the sample's time, its interval's end, inside [t0, t1]), for an ``exclude`` label and for a
  label whose segment is ``excluded``. A label ``exclude`` names that the log does not hold is
  an error: it is a typing mistake, not a choice.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from components.errors import LogFormatError
from components.logs.labels import SegmentLabels
from components.logs.rules import FORMAT, FORMAT_V2, RANGE_KEYS, XYZ, check_columns, check_samples, parse_metadata
from components.logs.spill import scaled

# a sample within this fraction of a declared output range counts as at it: a clipped output
# reads its full scale to the last bit, and a range written to four figures still finds it
RANGE_MARGIN = 1e-3


@dataclass
class MeasurementLog:
    time: np.ndarray                       # s, end of each sample interval
    gimbal: dict[str, np.ndarray]          # axis name -> measured angle [rad], base-to-plate order
    gyro: np.ndarray                       # (N, 3) as in the file (see gyro_output)
    acc: np.ndarray                        # (N, 3) as in the file (see acc_output)
    axis_names: list[str]
    axis_vectors: np.ndarray               # (n_axes, 3), unit vectors
    sample_rate_hz: float
    gyro_output: str = "increment"
    acc_output: str = "increment"
    gyro_count_rad: float | None = None
    acc_count_mps: float | None = None
    latitude_deg: float = 0.0
    height_m: float = 0.0
    gravity_mps2: float | None = None      # None: normal gravity at latitude and height
    description: str = ""
    command: dict[str, np.ndarray] = field(default_factory=dict)
    temperature: np.ndarray | None = None  # °C
    segment: SegmentLabels | None = None   # a label a sample (any array of str is taken as one)
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    extra_metadata: dict = field(default_factory=dict)  # unknown keys of the JSON, kept
    source: str | None = None
    # calbench-log/2 (all optional; a log using none of them is written as version 1)
    encoder_resolution: object = None      # None (not stated), "exact", or (n_axes,) one count [rad]
    timing: str = "nominal"                # "nominal" or "measured" (each sample's own interval)
    max_interval_s: float | None = None    # measured timing: a longer interval is a gap
    segments: dict | None = None           # label -> description, as in the file
    exclude: list = field(default_factory=list)  # time ranges [t0, t1] and labels to leave out
    noise: dict | None = None              # the noise model if known (calbench-noise/1 form)
    mask: np.ndarray | None = None         # (N,) bool, False: leave the sample out
    gyro_range: np.ndarray | None = None   # (3,) the gyros' output range (full scale) [rad/s], if known
    acc_range: np.ndarray | None = None    # (3,) the accelerometers' [m/s²]
    # (N, n_axes) the gimbal angles as one array when the reader filled them so (``gimbal``'s
    # arrays are then its columns): ``angles`` returns it instead of stacking a copy
    angle_matrix: np.ndarray | None = field(default=None, repr=False)
    # axis -> readings the reader found stepping by a whole turn and made continuous (the file's
    # angles read to one turn: components.logs.angle_turns)
    turns_mended: dict[str, int] = field(default_factory=dict)

    def __post_init__(self):
        if self.segment is not None and not isinstance(self.segment, SegmentLabels):
            try:
                self.segment = SegmentLabels.of(self.segment)
            except ValueError as e:
                raise LogFormatError(f"{self.source or 'log'}: column 'segment', {e}") from None

    # ----------------------------------------------------------------- derived
    @property
    def latitude(self) -> float:
        """Latitude [rad]."""
        return math.radians(self.latitude_deg)

    @property
    def dt(self) -> float:
        """Nominal sample interval [s]."""
        return 1.0 / self.sample_rate_hz

    @property
    def n(self) -> int:
        return len(self.time)

    @property
    def gravity(self) -> float:
        """Gravity magnitude [m/s²]: the logged value, else WGS-84 normal gravity."""
        if self.gravity_mps2 is not None:
            return self.gravity_mps2
        from components.model.geometry import normal_gravity

        return normal_gravity(self.latitude, self.height_m)

    @property
    def angles(self) -> np.ndarray:
        """(N, n_axes) gimbal angles [rad] in base-to-plate order ((N, 0) without a table)."""
        if not self.axis_names:
            return np.zeros((self.n, 0))
        m = self.angle_matrix
        if m is not None and all(np.shares_memory(self.gimbal[a], m) for a in self.axis_names):
            return m
        return np.column_stack([self.gimbal[a] for a in self.axis_names])

    @property
    def has_table(self) -> bool:
        """The log holds table angles (every version-1 log does)."""
        return bool(self.axis_names)

    @property
    def version(self) -> str:
        """The format this log needs: version 2 only when it uses a key of version 2."""
        v2 = (not self.axis_names or self.encoder_resolution is not None or self.timing != "nominal"
              or self.segments is not None or bool(self.exclude) or self.noise is not None or self.mask is not None
              or self.gyro_range is not None or self.acc_range is not None)
        return FORMAT_V2 if v2 else FORMAT

    def intervals(self, rows: slice = slice(None)) -> np.ndarray:
        """Each sample's interval [s] (of the samples *rows*, a slice with step 1: a long log a
        piece at a time): the nominal 1/sample_rate_hz, or with measured timing t[k] - t[k-1]
        (the first sample's nominal)."""
        a, b, _ = rows.indices(self.n)
        if self.timing != "measured":
            return np.full(max(b - a, 0), self.dt)
        if a == 0:
            return np.concatenate([[self.dt], np.diff(self.time[:b])])
        return np.diff(self.time[a - 1:b])

    def gaps(self, rows: slice = slice(None)) -> np.ndarray:
        """(rows,) bool: the sample's interval is longer than ``max_interval_s`` (default 1.5
        nominal intervals) under measured timing: its start is unknown (*rows* as for
        :meth:`intervals`)."""
        if self.timing != "measured":
            a, b, _ = rows.indices(self.n)
            return np.zeros(max(b - a, 0), bool)
        limit = self.max_interval_s if self.max_interval_s is not None else 1.5 * self.dt
        return self.intervals(rows) > limit

    def reasons_left_out(self, more: list | None = None) -> list:
        """Why samples may be left out, as (reason, a function from a slice of rows to their (rows,)
        bool mask): gaps, the mask, each ``exclude`` item (and *more*, e.g. the command line's
        ``--exclude``) and each excluded segment label; a label the log does not hold is refused
        here, naming the file. A reason may hit no sample (:meth:`left_out` lists only those that
        do). A function of a slice lets a long log be masked a piece at a time."""
        out: list = []
        if self.timing == "measured":
            out.append(("gap (the sample after it)", self.gaps))
        if self.mask is not None:
            out.append(("mask = 0", lambda s: ~np.asarray(self.mask[s], bool)))
        labels = None  # the log's segment labels, gathered only for a label to check (a set of
        # every sample's label was 0.2 s of each call on an 8-hour log)
        for item in list(self.exclude) + list(more or []):
            if isinstance(item, str):
                item = str(item)    # numpy's str_ too, so that messages show the plain label
                if labels is None:
                    labels = set(self.segment.distinct()) if self.segment is not None else set()
                if item not in labels:
                    raise LogFormatError(f"{self.source or 'log'}: exclude {item!r}: no segment has this label "
                                         f"(labels: {', '.join(sorted(map(str, labels))[:20]) or 'none'})")
                out.append((f"segment {item!r} (exclude)", lambda s, item=item: self.segment[s] == item))
            else:
                t0, t1 = item
                out.append((f"t = {t0:g}-{t1:g} s (exclude)",
                            lambda s, t0=t0, t1=t1: (self.time[s] >= t0) & (self.time[s] <= t1)))
        for lab, d in (self.segments or {}).items():
            if isinstance(d, dict) and d.get("kind") == "excluded" and self.segment is not None:
                out.append((f"segment {lab!r} (kind excluded)", lambda s, lab=lab: self.segment[s] == lab))
        for sensor, _, unit in RANGE_KEYS:
            full = getattr(self, f"{sensor}_range")
            if full is not None:
                said = f"±{full[0]:.6g}" if np.all(full == full[0]) else ", ".join(f"±{x:.6g}" for x in full)
                out.append((f"{sensor} at its output range ({said} {unit})",
                            lambda s, sensor=sensor, full=full: self._at_range(s, sensor, full)))
        return out

    def _at_range(self, rows: slice, sensor: str, full: np.ndarray) -> np.ndarray:
        """(rows,) bool: :func:`at_output_range` of the *sensor*'s mean rates or specific forces."""
        a, b, _ = rows.indices(self.n)
        lo, hi = max(a - 1, 0), min(b + 1, self.n)
        kind = getattr(self, f"{sensor}_output")
        x = np.abs(np.asarray(getattr(self, sensor)[lo:hi], float))
        if kind != "rate" and kind != "specific_force":
            weight = getattr(self, "gyro_count_rad" if sensor == "gyro" else "acc_count_mps") if kind == "counts" else 1.0
            dt = self.intervals(slice(lo, hi))[:, None] if self.timing == "measured" else self.dt
            x = x * (weight / dt)
        return at_output_range(x, full)[a - lo:a - lo + (b - a)]

    def left_out(self, more: list | None = None) -> dict[str, np.ndarray]:
        """Why samples are left out: {reason: (N,) bool} for the reasons of :meth:`reasons_left_out`
        that hit a sample (whole masks: :meth:`usable_into` is the one for a long log)."""
        out = {}
        for reason, hit in self.reasons_left_out(more):
            m = np.asarray(hit(slice(0, self.n)), bool)
            if m.any():
                out[reason] = m
        return out

    def usable(self, more: list | None = None) -> np.ndarray:
        """(N,) bool: the sample enters estimates (see :meth:`left_out`)."""
        ok = np.ones(self.n, bool)
        self.usable_into(ok, more)
        return ok

    def usable_into(self, out: np.ndarray, more: list | None = None, step: int | None = None) -> dict[str, int]:
        """Write into *out* (N,) whether each sample enters estimates, *step* samples at a time
        (default: a spill piece; *out* may be a spilled array), and return how many samples each
        reason leaves out (the reasons that leave some)."""
        from components.logs.spill import pieces

        reasons = self.reasons_left_out(more)
        counts = dict.fromkeys((r for r, _ in reasons), 0)
        for s in pieces(self.n, out, self.time, self.mask, step=step):
            ok = np.ones(s.stop - s.start, bool)
            for reason, hit in reasons:
                m = np.asarray(hit(s), bool)
                counts[reason] += int(np.count_nonzero(m))
                ok &= ~m
            out[s] = ok
        return {r: k for r, k in counts.items() if k}

    def gyro_increment(self) -> np.ndarray:
        """(N, 3) angle increments [rad] over each sample interval."""
        return _to_increment(self.gyro, self.gyro_output, self._rate_intervals(self.gyro_output), self.gyro_count_rad)

    def acc_increment(self) -> np.ndarray:
        """(N, 3) velocity increments [m/s] over each sample interval."""
        return _to_increment(self.acc, self.acc_output, self._rate_intervals(self.acc_output), self.acc_count_mps)

    def _rate_intervals(self, kind: str):
        if kind not in ("rate", "specific_force") or self.timing != "measured":
            return self.dt
        return self.intervals()[:, None]

    def gyro_rate(self) -> np.ndarray:
        """(N, 3) mean angular rate [rad/s] over each interval."""
        return self.gyro_increment() / self.intervals()[:, None]

    def specific_force(self) -> np.ndarray:
        """(N, 3) mean specific force [m/s²] over each interval."""
        return self.acc_increment() / self.intervals()[:, None]

    def metadata(self) -> dict:
        """The JSON metadata of this log."""
        v2 = self.version == FORMAT_V2
        meta = {
            "format": self.version,
            "site": {"latitude_deg": self.latitude_deg, "height_m": self.height_m,
                     "gravity_mps2": self.gravity_mps2},
            "table": {"axes": [{"name": n, "axis": [float(x) for x in v]}
                               for n, v in zip(self.axis_names, self.axis_vectors)]},
            "imu": {"sample_rate_hz": self.sample_rate_hz, "gyro_output": self.gyro_output,
                    "acc_output": self.acc_output, "gyro_count_rad": self.gyro_count_rad,
                    "acc_count_mps": self.acc_count_mps},
            "description": self.description,
        }
        if v2:
            res = self.encoder_resolution
            if res is not None:
                meta["table"]["encoder_resolution_rad"] = res if isinstance(res, str) else \
                    [float(x) for x in np.broadcast_to(res, (len(self.axis_names),))]
            if self.timing != "nominal":
                meta["imu"]["timing"] = self.timing
            if self.max_interval_s is not None:
                meta["imu"]["max_interval_s"] = self.max_interval_s
            if self.noise is not None:
                meta["imu"]["noise"] = self.noise
            if self.segments is not None:
                meta["segments"] = self.segments
            if self.exclude:
                meta["exclude"] = self.exclude
            for sensor, key, _ in RANGE_KEYS:
                full = getattr(self, f"{sensor}_range")
                if full is not None:
                    meta["imu"][key] = [float(x) for x in full]
        for k, v in self.extra_metadata.items():
            meta.setdefault(k, v)
        return meta

    def columns(self) -> dict[str, np.ndarray]:
        """The sample columns in the spec's order."""
        cols: dict[str, np.ndarray] = {"time": self.time}
        for a in self.axis_names:
            cols[f"gimbal_{a}"] = self.gimbal[a]
        for a in self.axis_names:
            if a in self.command:
                cols[f"command_{a}"] = self.command[a]
        for j, c in enumerate(XYZ):
            cols[f"gyro_{c}"] = self.gyro[:, j]
        for j, c in enumerate(XYZ):
            cols[f"acc_{c}"] = self.acc[:, j]
        if self.temperature is not None:
            cols["temperature"] = self.temperature
        if self.segment is not None:
            cols["segment"] = self.segment
        if self.mask is not None:
            cols["mask"] = self.mask.astype(np.int8)
        cols.update(self.extra)
        return cols

    def validate(self, where: str = "measurement log") -> None:
        """Check this log against the rules (what :func:`read_log` enforces on files)."""
        meta = parse_metadata(self.metadata(), where)
        cols = self.columns()
        check_columns(list(cols), meta, where)
        check_samples(cols, meta, where, lambda i: f"sample {i + 1}")


def at_output_range(magnitude: np.ndarray, full: np.ndarray) -> np.ndarray:
    """(n,) bool: a sample whose mean rate or specific force *magnitude* (n, 3), each axis's
    absolute value, reaches the output range *full* (3,) on any axis (within RANGE_MARGIN), and
    the sample either side of it: a clipped output reads the range whatever the input beyond it,
    and the samples whose interval the input crossed the range in read a mix."""
    hit = np.any(magnitude >= np.asarray(full) * (1 - RANGE_MARGIN), axis=1)
    near = hit.copy()
    near[1:] |= hit[:-1]
    near[:-1] |= hit[1:]
    return near


def _to_increment(x: np.ndarray, kind: str, dt, weight: float | None) -> np.ndarray:
    if kind == "increment":
        return x
    if kind == "counts":
        return scaled(x, weight)
    return scaled(x, dt)  # rate or specific_force
