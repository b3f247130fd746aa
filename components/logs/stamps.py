"""The time columns of a rig's files as the samples' times [s]: numbers in the mapping's unit or
clock readings (ISO 8601 dates, the time of day: components.logs.sources.clock_seconds), counted
on where a counter rolls over (``rollover``), and checked before anything uses them: never back,
strictly increasing unless a regular grid will replace them (a host clock coarser than the
samples stamps several alike), the stated sample rate within a factor."""
from __future__ import annotations

import math

import numpy as np

from components.errors import MappingError
from components.logs.mapping import Mapping
from components.logs.sources import Columns
from components.logs.timebase import regularise, stamp_resolution, unrolled

# stamps whose median interval is this far from 1/sample_rate_hz (either way) are in another unit
# than the mapping says, or the rate is wrong: not a clock's drift (ppm) nor a jitter
RATE_MISMATCH = 1.25



def imu_stamps(m: Mapping, cols: Columns, notes: list[str]) -> tuple[np.ndarray, float, float]:
    """(the IMU file's stamps [s], the resolution of a clock coarser than the samples or 0, the
    longest interval that is not a gap [s])."""
    t, rolled = unrolled(_clock(cols, m.time, "imu.time", m.time_si, m.where, notes), m.time_rollover_s)
    if len(t) < 2:
        raise MappingError(f"{cols.where}: fewer than two samples")
    if rolled:
        notes.append(f"the time counter rolled over {rolled} time(s) (imu.time.rollover: every "
                     f"{m.time_rollover_s:.10g} s); counted on")
    _in_order(t, m.timing == "regularise", cols.where, "imu.time", m.time_rollover_s)
    nominal = 1.0 / m.sample_rate_hz
    tick = stamp_resolution(t, nominal if m.timing == "regularise" else None)
    _check_rate(m, t, nominal, tick, "imu", m.time_si)
    max_int = m.max_interval_s if m.max_interval_s is not None else 1.5 * nominal
    if tick:
        shared = float(np.mean(np.diff(t) == 0))
        # an interval between two ticks is up to a tick longer than the samples' own
        max_int += tick
        notes.append(f"time stamps of a clock of {tick * 1e3:.4g} ms resolution ({shared:.0%} of the intervals zero); "
                     f"a gap is an interval beyond {max_int * 1e3:.4g} ms (a sample lost inside a tick is not seen)")
    return t, tick, max_int


def table_stamps(m: Mapping, tc: Columns, notes: list[str]) -> np.ndarray:
    """The table file's times [s], strictly increasing (its angles are interpolated between
    them): its stamps, or with ``table.time.timing = "regularise"`` the grid fitted to stamps that
    may repeat (a host polling the controller, stamping with a clock coarser than its polls)."""
    tt, rolled = unrolled(_clock(tc, m.table_time, "table.time", m.table_time_si, m.where, notes),
                          m.table_time_rollover_s)
    if rolled:
        notes.append(f"{tc.where}: the table's time counter rolled over {rolled} time(s) (table.time.rollover: every "
                     f"{m.table_time_rollover_s:.10g} s); counted on")
    repeats = m.table_timing == "regularise"
    _in_order(tt, repeats, tc.where, "table.time", m.table_time_rollover_s,
              " (stamps that repeat, a clock coarser than the table's samples: give table.time.timing = 'regularise' "
              "and table.sample_rate_hz)")
    if not repeats:
        return tt
    nominal = 1.0 / m.table_rate_hz
    tick = stamp_resolution(tt, nominal)
    _check_rate(m, tt, nominal, tick, "table", m.table_time_si)
    reg = regular_grid(tt, nominal, 1.5 * nominal + tick, tc, "table.time")
    notes.append(f"{tc.where}: table stamps regularised"
                 + (f" (a clock of {tick * 1e3:.4g} ms resolution, {float(np.mean(np.diff(tt) == 0)):.0%} of the "
                    "intervals zero)" if tick else "")
                 + f": {reg.runs} run(s), fitted rate {reg.rate_hz:.6f} Hz, stamps' RMS scatter {reg.jitter_rms_s * 1e3:.3g} ms")
    return reg.time


def regular_grid(t: np.ndarray, nominal: float, max_interval: float, cols: Columns, key: str,
                 index: np.ndarray | None = None):
    """components.logs.timebase.regularise of the stamps *t* of *cols*' time column *key*, its
    grid checked to advance: where jitter passes for gaps, the runs between them are placed by
    their own stamps and their grids can overlap (a log with two samples at one time, refused
    only by the log's own check, naming the log's sample). One error at the file's row, naming
    the sample counter that tells lost samples from late stamps."""
    reg = regularise(t, nominal, max_interval, index)
    back = np.diff(reg.time) <= 0
    if back.any():
        i = int(np.argmax(back)) + 1
        counter = "give [imu.counter] (the sensor's sample counter) if the file has one, else " if key == "imu.time" else ""
        raise MappingError(f"{cols.where}: {key}: the regular grids fitted to the stamps between what look like gaps "
                           f"overlap at row {cols.file_row(i)} (the stamps' jitter {reg.jitter_rms_s * 1e6:.3g} us RMS, "
                           f"a gap beyond {max_interval * 1e3:g} ms): at this jitter the stamps do not tell a lost sample "
                           f"from a late stamp; {counter}a max_interval_s that no late stamp reaches")
    return reg


def _in_order(t: np.ndarray, repeats: bool, where: str, key: str, rollover_s: float | None,
              repeat_hint: str = "") -> None:
    """Stamps *t* of the time column *key* that never go back and, unless a regular grid will
    replace them (*repeats*: a host's clock coarser than the samples stamps several alike, and a
    grid fitted to all of them places the samples as well), strictly increase; one error at the
    first row that breaks it (*repeat_hint*: what to give where a stamp merely repeats)."""
    back = np.diff(t) < 0 if repeats else np.diff(t) <= 0
    if np.any(back):
        i = int(np.argmax(back)) + 1
        raise MappingError(f"{where}: {key}: row {i + 1}: {float(t[i])!r} s after {float(t[i - 1])!r} s; expected "
                           + ("times that never go back" if repeats else "strictly increasing times"
                              + (repeat_hint if t[i] == t[i - 1] else ""))
                           + _rollover_hint(t, i, rollover_s, key))
    if repeats and t[-1] == t[0]:
        raise MappingError(f"{where}: {key}: every stamp is {float(t[0])!r} s; expected times that advance")


def _clock(cols: Columns, ch, key: str, unit_si: float, where: str, notes: list[str]) -> np.ndarray:
    """A time column in seconds: numbers in *key*.unit, or clock readings (dates and times, the
    time of day: components.logs.sources.clock_seconds), which are seconds already."""
    t, read = cols.times(ch, f"{key}.column")
    if read is None:
        return t * unit_si
    if unit_si != 1.0:
        raise MappingError(f"{where}: key '{key}.unit': the column {ch.column!r} holds {read} ({cols.where}), read as "
                           "seconds; expected no unit (or 's')")
    notes.append(f"{cols.where}: {key}: {read} read as seconds since "
                 + ("1970-01-01 (UTC where the file gives a zone)" if read == "dates" else
                    f"midnight (a log past midnight: give '{key}.rollover' = 86400)"))
    return t


def _rollover_hint(t: np.ndarray, i: int, period: float | None, key: str) -> str:
    """What to give where time steps back at row *i* by more than a few samples' worth: a
    counter that rolls over, unless its period is given already."""
    if period is not None:
        return ""
    back = float(t[i - 1] - t[i])
    usual = float(np.median(np.diff(t[max(0, i - 1000):i]))) if i > 1 else 0.0
    if not back > (100 * usual if usual > 0 else 1.0):
        return ""
    return (f" (back by {back:.10g} s: a counter that rolls over? give '{key}.rollover', its period in '{key}.unit', "
            "e.g. 4294967296 for a 32-bit count of microseconds)")


def _check_rate(m: Mapping, t: np.ndarray, nominal: float, tick: float, file: str, unit_si: float) -> None:
    """The time stamps against the stated sample rate: a unit or a rate off by a factor (ms read
    as s: every interval a gap) is named here, with the mapping's keys, not by what it breaks later.
    Stamps of a clock with a *tick* coarser than the samples: the median interval over enough
    samples to span eight ticks (one tick off in eight is within the factor looked for)."""
    k = max(1, math.ceil(8 * tick / nominal))
    d = (t[k:] - t[:-k]) / k if len(t) > k else np.diff(t)
    med = float(np.median(d[::max(1, len(d) // (1 << 20))]))  # a factor is all it looks for: 1 M intervals do
    ratio = med / nominal
    if not 1 / RATE_MISMATCH < ratio < RATE_MISMATCH:
        raise MappingError(f"{m.where}: the {file} file's time stamps' median interval is {med:.6g} s ({file}.time.unit: "
                           f"{unit_si:g} s a unit), {ratio:.4g} x 1/{file}.sample_rate_hz = {nominal:.6g} s; expected "
                           f"the same within 25 %: check {file}.time.unit and {file}.sample_rate_hz")
