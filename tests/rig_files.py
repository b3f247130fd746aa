"""The conformance log written as another rig's files, for the import's tests: a CSV of the
columns a test chooses (numbers to the bit, or text cells as the test writes them) and the
mapping that reads it back. The IMU file's columns are t, gx..gz, ax..az and, with the angles
in it, A, B, C (degrees); a table file's are t, A, B, C."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from components.cli import main
from components.logs.logfile import read_log

AXES = ("outer", "middle", "inner")
INCREMENTS = ('output = "increment"\nunit = "rad"', 'output = "increment"\nunit = "m/s"')


def write_csv(path: Path, columns: dict) -> None:
    """A CSV of *columns*: name -> numbers (written to the bit) or text cells ('' an empty one)."""
    cells = [[f"{v:.17g}" for v in c] if isinstance(c, np.ndarray) else list(c) for c in columns.values()]
    path.write_text(",".join(columns) + "\n" + "".join(",".join(row) + "\n" for row in zip(*cells)))


def imu_columns(log, time, gyro=None, acc=None, angles: bool = True) -> dict:
    """The IMU file's columns: *time* (numbers or text), the increments (or *gyro*, *acc* in
    their place) and, with *angles*, the table's angles in degrees."""
    gyro = log.gyro if gyro is None else gyro
    acc = log.acc if acc is None else acc
    out = {"t": time, **{f"g{k}": gyro[:, i] for i, k in enumerate("xyz")},
           **{f"a{k}": acc[:, i] for i, k in enumerate("xyz")}}
    if angles:
        out.update({c: np.degrees(log.gimbal[a]) for c, a in zip("ABC", AXES)})
    return out


def table_columns(log, time) -> dict:
    """A table file's columns: *time* and the angles in degrees."""
    return {"t": time, **{c: np.degrees(log.gimbal[a]) for c, a in zip("ABC", AXES)}}


def mapping(log, time: str = "", gyro: str = INCREMENTS[0], acc: str = INCREMENTS[1], temperature: str = "",
            table: str = "", table_time: str | None = None) -> str:
    """The mapping of imu.csv: *time* the keys of [imu.time] beside its column, *gyro* and *acc*
    the sensors' keys beside their columns, *temperature* the keys of [imu.temperature] (none:
    no temperature); *table* the keys of [table], and *table_time* those of [table.time] when the
    angles are in table.csv (None: in imu.csv)."""
    sensors = "".join(f"[imu.{s}]\n{keys}\n" + "".join(f'{k} = "{p}{k}"\n' for k in "xyz")
                      for s, keys, p in (("gyro", gyro, "g"), ("acc", acc, "a")))
    axes = "".join(f'[[table.axes]]\nname = "{n}"\naxis = {list(map(int, v))}\ncolumn = "{c}"\nunit = "deg"\n'
                   for n, v, c in zip(AXES, log.axis_vectors, "ABC"))
    text = f'[imu]\nfile = "imu.csv"\nsample_rate_hz = {log.sample_rate_hz!r}\n[imu.time]\ncolumn = "t"\n{time}\n{sensors}'
    if temperature:
        text += f'[imu.temperature]\ncolumn = "temp"\n{temperature}\n'
    text += "[table]\n" + ('file = "table.csv"\n' if table_time is not None else "") + f'{table}\nencoder_resolution = "exact"\n'
    if table_time is not None:
        text += f'[table.time]\ncolumn = "t"\n{table_time}\n'
    return text + axes + f"[site]\nlatitude_deg = {log.latitude_deg!r}\nheight_m = {log.height_m!r}\n"


def imported(directory: Path, name: str = "merged"):
    """``calbench import`` of directory/map.toml, read back."""
    assert main(["import", str(directory / "map.toml"), "--out", str(directory / name)]) == 0
    return read_log(directory / name)
