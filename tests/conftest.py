import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from fmus.build import fmu_path  # noqa: E402


@pytest.fixture(scope="session")
def turntable_fmu() -> Path:
    return fmu_path("turntable", 2)


@pytest.fixture(scope="session")
def imu_fmu() -> Path:
    return fmu_path("imu", 2)
