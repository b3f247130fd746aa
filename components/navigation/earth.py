"""Site constants for a stationary navigation solution: latitude is fixed (the IMU stays on the
table), so gravity, Earth rate and the meridian / prime-vertical radii are constants."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.model.geometry import EARTH_RATE, earth_rate_enu, normal_gravity

_A = 6378137.0
_E2 = 0.00669437999013


@dataclass(frozen=True)
class Site:
    latitude: float  # rad
    height: float = 0.0
    gravity: float | None = None
    earth_rate: float = EARTH_RATE

    @property
    def g(self) -> float:
        return self.gravity if self.gravity else normal_gravity(self.latitude, self.height)

    @property
    def g_n(self) -> np.ndarray:
        return np.array([0.0, 0.0, -self.g])

    @property
    def w_ie(self) -> np.ndarray:
        return earth_rate_enu(self.latitude, self.earth_rate)

    @property
    def rm(self) -> float:
        s2 = math.sin(self.latitude) ** 2
        return _A * (1 - _E2) / (1 - _E2 * s2) ** 1.5 + self.height

    @property
    def rn(self) -> float:
        s2 = math.sin(self.latitude) ** 2
        return _A / math.sqrt(1 - _E2 * s2) + self.height

    @classmethod
    def of_geometry(cls, geo) -> "Site":
        return cls(geo.latitude, geo.height, geo.gravity, geo.earth_rate)
