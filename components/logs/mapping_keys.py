"""The keys each table of an import mapping takes (docs/import.md lists them all): any other is
a typing mistake, refused with the nearest known key (a misspelt 'rollover' or 'accumulated' read
as absent would import wrong numbers without a word)."""
from __future__ import annotations

from components.errors import MappingError

SOURCE_KEYS = ("file", "format", "delimiter", "decimal", "skip_rows", "header", "lost_rows")
KEYS = {
    "": ("description", "exclude", "imu", "labels", "segments", "table", "site"),
    "imu": SOURCE_KEYS + ("sample_rate_hz", "time", "counter", "gyro", "acc", "temperature"),
    "imu.counter": ("column", "rollover", "step"),
    "imu.time": ("column", "unit", "timing", "keeps_time", "max_interval_s", "rollover"),
    "imu.gyro": ("output", "unit", "count", "scale", "offset", "accumulated", "rollover", "range", "x", "y", "z"),
    "imu.temperature": ("column", "unit", "sparse", "scale", "offset"),
    "labels": ("column", "ranges"),
    "labels.ranges": ("from", "to", "label"),
    "table": SOURCE_KEYS + ("sample_rate_hz", "time", "clock_offset_s", "clock_rate_ppm", "axes", "encoder_resolution",
                            "round_to_count"),
    "table.time": ("column", "unit", "timing", "rollover", "clock"),
    "table.axes": ("name", "axis", "column", "unit", "command", "scale", "offset"),
    "site": ("latitude_deg", "height_m", "gravity_mps2"),
}
KEYS["imu.acc"] = KEYS["imu.gyro"]


def check_keys(d: dict, table: str, where: str, name: str | None = None) -> None:
    """Every key of *d*, the mapping's *table* (KEYS; *name*: as the user wrote it, e.g.
    'table.axes[1]'), is one calbench reads; else one error naming it and the nearest known key."""
    import difflib

    known = KEYS[table]
    for k in d:
        if k not in known:
            near = difflib.get_close_matches(k, known, n=1)
            at = f"{name or table}.{k}" if table else k
            raise MappingError(f"{where}: key {at!r} is not one calbench reads"
                               + (f" (did you mean '{near[0]}'?)" if near else "")
                               + f"; {f'[{name or table}]' if table else 'the top level'} takes: {', '.join(known)}")
