"""What the estimators need from a measurement log: time, measured angles, increments in SI,
the table geometry of its metadata, and the plate motion interpolated from the angles."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from components.estimation import order_statistics
from components.estimation.rest_angles import encoder_quantum
from components.logs import spill
from components.logs.labels import SegmentLabels
from components.logs.spill import both, empty_like_log, gathered, pieces, release
from components.model.approach import run_sides
from components.model.geometry import Stage, TableGeometry
from components.model.motion import Motion, interpolate_angles, motion_from_profile, same_as_before
from components.model.noise import CHANNELS


@dataclass
class LogData:
    """What the estimators need from a measurement log, in SI (increments per interval)."""

    time: np.ndarray
    angles: np.ndarray  # (N, n_axes) measured
    gyro: np.ndarray    # (N, 3) increments [rad]
    acc: np.ndarray     # (N, 3) increments [m/s]
    geometry: TableGeometry
    temperature: np.ndarray | None = None
    segment: SegmentLabels | None = None  # (any array of str is taken as one)
    dt0: float | None = None
    source: dict = field(default_factory=dict)
    # count weight of a pulse output [rad, m/s] (gyro, accelerometer), None for other outputs:
    # the quantization term of the noise is known from it
    count_weight: tuple = (None, None)
    # samples that enter estimates (False: a gap, the mask, an exclusion); None: all
    valid: np.ndarray | None = None
    # why samples are left out: reason -> count (shown by every command)
    left_out: dict = field(default_factory=dict)
    # one encoder count per axis [rad], "exact", or None (not stated: the smallest logged step)
    encoder_resolution: object = None
    # what each segment label is, as in the log's metadata (components.logs.segments)
    segments: dict | None = None
    # the log's own noise model (calbench-noise/1 form) if its metadata states one
    noise: dict | None = None
    # the time drift terms count from [s]; None: the start of the first sample's interval. A
    # stretch of a longer log (LogData.stretch) keeps the whole log's
    time_origin: float | None = None
    # the side each stage last moved to before the first sample (+1, -1, 0: none); a stretch of a
    # longer log (LogData.stretch) keeps the whole log's, which a table's reversal error needs
    approach0: np.ndarray | None = None
    # per stage [rad], what a stage must travel for its side to count (two encoder counts: a rest
    # whose reading dithers a count keeps its side); None: from this log, when first needed
    side_band: np.ndarray | None = None
    _profiles: dict = field(default_factory=dict, repr=False, compare=False)
    _interval: float | None = field(default=None, repr=False, compare=False)
    _static: np.ndarray | None = field(default=None, repr=False, compare=False)
    _sides: tuple | None = field(default=None, repr=False, compare=False)
    # (not an init field: a copy made with dataclasses.replace, another mask perhaps, starts empty)
    _rest_white: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.segment is not None:
            self.segment = SegmentLabels.of(self.segment)

    @property
    def sample_interval(self) -> float:
        """The median sample interval [s] (a jittered clock's nominal one), computed once: on an
        8-hour log each median of the intervals was ~0.4 s, and a command took it in several places."""
        if self._interval is None:
            self._interval = self.interval_median() if len(self.time) > 1 else float("nan")
        return self._interval

    def interval_median(self, first: float | None = None) -> float:
        """The median of the intervals between consecutive sample times, with *first* (an
        interval before them) among them if given; exact (np.median's value), a piece of the log
        at a time: a long log's intervals are not made whole (240 MB on an 8-hour log)."""
        t = self.time
        n = len(t) - 1

        def intervals():
            if first is not None:
                yield np.array([first])
            for s in pieces(n, t):
                yield np.diff(t[s.start:s.stop + 1])

        at = np.arange(0, n, order_statistics.stride(n))
        sample = gathered(t, at + 1) - gathered(t, at)
        return order_statistics.median_of_pieces(intervals, n + (first is not None), sample)

    @property
    def has_table(self) -> bool:
        return self.angles.shape[1] > 0

    @property
    def segment_kinds(self) -> dict | None:
        """The segment descriptions checked (components.logs.segments.parse_segments)."""
        if not self.segments:
            return None
        from components.logs.segments import parse_segments

        return parse_segments(self.segments)

    def quantization_floor(self, noise=None) -> np.ndarray:
        """Per channel (gyro x y z, acc x y z), the σ one count leaves in a sample of a pulse
        output (w/√12, uniform), 0 for other outputs: the least white noise such a sample has.
        0 too where *noise* (components.model.noise.NoiseModel) carries the quantization as a
        term of its own, which must not be counted twice."""
        q = np.repeat([(w or 0.0) / np.sqrt(12.0) for w in self.count_weight], 3)
        if noise is not None:
            q = np.where([c.quantization > 0 for c in noise.channels], 0.0, q)
        return q

    def without_white_level(self, white: np.ndarray, noise=None) -> list[str]:
        """The channels of a pulse output (CHANNELS names) whose white level is 0: in *white*
        (per channel, from the data) and in *noise*'s white part if given. Either the IMU has
        none (a noise-free simulation: its counts' quantization is the whole noise, and a fit is
        right) or its counts are too coarse for this log to show it, and a numerical floor
        stands in for it: σ too small by up to a hundred times (2" counts at 100 Hz: 98σ off).
        χ²/dof tells which (in its band, or far above it); calibrate and compare say so."""
        if noise is not None:
            white = np.maximum(white, noise.white_sigma(self.sample_interval))
        return [name for name, hidden in zip(CHANNELS, self._counted() & ~(np.asarray(white) > 0)) if hidden]

    def _counted(self) -> np.ndarray:
        """(6,) bool: the channels of a pulse output."""
        return np.repeat([w is not None and w > 0 for w in self.count_weight], 3)

    def white_poorly_read(self, noise=None) -> list[str]:
        """The channels of a pulse output whose white level *noise* (an identified model) holds
        but did not measure (NoiseModel.white_poorly_read): the counts hide it nearly as much as
        where none was found, and a level read low leaves σ too small. [] without a model."""
        if noise is None:
            return []
        poor = noise.white_poorly_read()
        return [name for name, c in zip(CHANNELS, self._counted()) if c and name in poor]

    @property
    def usable(self) -> np.ndarray:
        """(N,) bool: the samples that enter estimates."""
        # (every sample: one True seen N times, not N bytes made at each call)
        return np.broadcast_to(np.True_, (len(self.time),)) if self.valid is None else self.valid

    @property
    def static_usable(self) -> np.ndarray:
        """(N,) bool: at rest and usable, the samples a per-sample noise statistic reads (on disk
        for a spilled log, as the static mask)."""
        return both(self.static, self.valid)

    def white_sigma_at_rest(self, sensor: str) -> np.ndarray:
        """The data's per-sample white σ (3,) of the gyro or accelerometer increments over the
        usable rest samples (components.estimation.blocks.white_noise_sigma, without a floor),
        computed once: a pass over the whole log that calibrate and diagnose each needed twice."""
        if sensor not in self._rest_white:
            from components.estimation.blocks import white_noise_sigma

            increments = {"gyro": self.gyro, "acc": self.acc}[sensor]
            sigma = white_noise_sigma(increments, self.static_usable)
            sigma.setflags(write=False)
            self._rest_white[sensor] = sigma
        return self._rest_white[sensor]

    def angle_profile(self, quadrature: int = 3):
        """The interpolated gimbal angles (cached: they do not depend on the geometry)."""
        if quadrature not in self._profiles:
            self._profiles[quadrature] = interpolate_angles(self.time, self.angles, quadrature, self.dt0,
                                                            self.approach0, self.band())
        return self._profiles[quadrature]

    @property
    def static(self) -> np.ndarray:
        """(N,) bool: no gimbal angle changed over the sample's interval (the first sample's
        interval is taken at rest), as the angle profile has it, without building the profile.
        Without a table the samples of the segments of kind 'static'. Computed once
        (a command asked five times: 0.34 s each on an 8-hour log) and read-only, being shared."""
        if self._static is None:
            if not self.has_table:
                # at rest: the samples of the segments described as static; without descriptions
                # every sample (the turns of such a log are not known apart from its rests)
                kinds = self.segment_kinds if self.segment is not None else None
                rests = [lab for lab, d in (kinds or {}).items() if d["kind"] == "static"]
                st = self.segment.isin(rests) if rests else np.ones(len(self.time), bool)
            else:
                # a piece at a time: a spilled log's angles are not brought into memory whole; and
                # on disk beside them (a byte a sample: the most of what a long log's command kept)
                a = self.angles
                # (a chunk's window keeps its own in memory: a file each would cost more than it saves)
                st = empty_like_log(len(a), a, bool) if len(a) > spill.PIECE else np.empty(len(a), bool)
                st[:1] = True
                for s in pieces(len(a) - 1, a, st):
                    same_as_before(a[s.start:s.stop + 1], out=st[s.start + 1:s.stop + 1])
            st.setflags(write=False)
            self._static = st
        return self._static

    @property
    def start_time(self) -> float:
        """The start of the first sample's interval: the time drift terms count from."""
        if self.time_origin is not None:
            return self.time_origin
        dt0 = self.dt0 if self.dt0 is not None else (self.time[1] - self.time[0] if len(self.time) > 1 else 0.0)
        return float(self.time[0] - dt0)

    def motion(self, geometry: TableGeometry, t0_temperature: float | None = None,
               quadrature: int = 3) -> Motion:
        return motion_from_profile(self.angle_profile(quadrature), geometry, self.temperature,
                                   t0_temperature, time_origin=self.time_origin)

    def times_at(self, index: np.ndarray) -> np.ndarray:
        """time[index]; for a spilled log a piece of it at a time, each piece's pages given back
        (components.logs.spill.gathered)."""
        return gathered(self.time, index)

    def release(self) -> None:
        """Give back the pages of spilled sensor columns a pass has touched (components.logs.spill;
        nothing for a log in memory)."""
        release(self.time, self.angles, self.gyro, self.acc, self.temperature, self._static, self.valid)

    def stretch(self, a: int, b: int) -> "LogData":
        """Samples a-1..b-1 of the log as a log of their own that computes exactly what the whole
        log computes for samples a..b-1: sample a-1 leads (its interval is taken at rest, so it
        must be a rest sample, and it gives sample a the start of its interval and the
        temperature before it); drift terms count from the whole log's start. The estimators'
        chunks (components.estimation.chunks)."""
        lead = max(a - 1, 0)
        view = self.window(lead, b)
        view.time_origin = self.start_time
        view.dt0 = self.dt0 if lead == 0 else float(self.time[lead] - self.time[lead - 1])
        return view

    def window(self, a: int, b: int) -> "LogData":
        """Samples a..b-1 (a stage of a schedule), the same site, table and sample interval."""
        cut = lambda x: None if x is None else x[a:b]  # noqa: E731
        return replace(self, time=self.time[a:b], angles=self.angles[a:b], gyro=self.gyro[a:b],
                       acc=self.acc[a:b], temperature=cut(self.temperature),
                       segment=cut(self.segment), valid=cut(self.valid), _profiles={},
                       _interval=None, _static=None, approach0=self.approach_at(a), side_band=self.band(),
                       _sides=None)

    def band(self) -> np.ndarray:
        """(n_axes,) [rad]: two encoder counts (stated, else the smallest logged step)."""
        if self.side_band is None:
            res = self.encoder_resolution
            count = np.broadcast_to(np.asarray(res, float), (self.angles.shape[1],)) \
                if res is not None and not isinstance(res, str) else encoder_quantum(self.angles)
            self.side_band = 2.0 * count
        return self.side_band

    def approach_at(self, i: int) -> np.ndarray:
        """(n_axes,) int8: the side each stage is on at sample *i* (+1, -1, 0: none), after this
        log's moves before it (components.model.approach.run_sides)."""
        if self._sides is None:
            start = np.zeros(self.angles.shape[1], np.int8) if self.approach0 is None else self.approach0
            # a spilled log's pages of each run go back after it: the runs are spread over the
            # whole log, and each read maps a large stretch of the file (0.7 GB on an 8-hour log)
            runs, after, _ = run_sides(self.angles, self.static, start, self.band(),
                                       after_run=partial(release, self.angles))
            self._sides = (np.array([b for _, b in runs], np.int64), after, np.asarray(start, np.int8))
        ends, after, start = self._sides
        r = np.searchsorted(ends, i, side="right") - 1  # the last run over by sample i
        return np.array(after[r] if r >= 0 else start, np.int8, copy=True)

    @classmethod
    def from_log(cls, log, exclude: list | None = None) -> "LogData":
        """From a components.logs.logfile.MeasurementLog; ``exclude``: more time ranges
        [t0, t1] and segment labels to leave out (the command line's ``--exclude``)."""
        geo = TableGeometry(tuple(Stage(n, tuple(float(x) for x in v))
                                  for n, v in zip(log.axis_names, log.axis_vectors)),
                            latitude=log.latitude, height=log.height_m, gravity=log.gravity)
        gyro, acc = log.gyro_increment(), log.acc_increment()
        # the usable mask a piece at a time, spilled with a spilled log: a byte a sample, and
        # no whole mask per reason beside it
        valid = empty_like_log(log.n, gyro, bool)
        left_out = log.usable_into(valid, exclude)
        if not left_out:
            valid = None
        _check_range(log, gyro, acc, valid)
        return cls(time=log.time, angles=log.angles, gyro=gyro,
                   acc=acc, geometry=geo, temperature=log.temperature,
                   segment=log.segment, dt0=log.dt, source={"log": log.source},
                   count_weight=(log.gyro_count_rad if log.gyro_output == "counts" else None,
                                 log.acc_count_mps if log.acc_output == "counts" else None),
                   valid=valid, left_out=left_out,
                   encoder_resolution=log.encoder_resolution,
                   segments=log.segments, noise=log.noise)


# beyond any inertial sensor's range: a corrupt value, not a measurement (an estimate would
# overflow on it, or silently be dominated by it)
MAX_RATE = 1.0e3      # rad/s (57 000 deg/s; the fastest MEMS gyros stop at ~70 rad/s)
MAX_FORCE = 1.0e5     # m/s² (10 000 g)


def _check_range(log, gyro: np.ndarray, acc: np.ndarray, valid) -> None:
    from components.errors import EstimationError

    def first_beyond(inc, limit):
        # in pieces: the whole log's intervals, quotient and mask would be 35 bytes a sample at once
        for s in pieces(log.n, inc, log.time):
            with np.errstate(over="ignore", invalid="ignore"):
                bad = ~(np.abs(inc[s] / log.intervals(s)[:, None]) <= limit)
            if valid is not None:
                bad &= valid[s, None]
            if bad.any():
                i, k = np.argwhere(bad)[0]
                return s.start + i, k
        return None

    for name, inc, limit, unit in (("gyro", gyro, MAX_RATE, "rad/s"), ("acc", acc, MAX_FORCE, "m/s²")):
        hit = first_beyond(inc, limit)
        if hit is not None:
            i, k = hit
            dt = float(log.intervals(slice(i, i + 1))[0])
            with np.errstate(over="ignore"):
                value = inc[i, k] / dt
            raise EstimationError(
                f"{log.source or 'log'}: sample {i + 1} (t = {log.time[i]:.6g} s), column {name}_{'xyz'[k]}: "
                f"{inc[i, k]:.4g} per {dt:g} s ({value:.4g} {unit}) is beyond any {'gyro' if name == 'gyro' else 'accelerometer'}'s "
                f"range (|value| <= {limit:g} {unit}): a corrupt value, or a wrong unit or count weight; mask or "
                "exclude it, or fix the metadata")
