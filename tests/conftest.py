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


CONFORMANCE_DATA = Path(__file__).parent / "data" / "conformance"


@pytest.fixture(scope="session")
def conformance(tmp_path_factory) -> Path:
    """The independent simulator's calbench-log/1 conformance vectors (tests/data/README.md):
    a directory holding ideal.csv/.json, example.csv/.json and example.truth.json, unpacked
    from tests/data/conformance once per session. Every file's SHA-256 must match
    tests/data/conformance/SHA256SUMS: a missing or altered file fails the tests that use it,
    it never skips them."""
    import hashlib
    import lzma

    sums = CONFORMANCE_DATA / "SHA256SUMS"
    if not sums.is_file():
        pytest.fail(f"{sums} is missing: the conformance vectors cannot be checked", pytrace=False)
    expected = {}
    for line in sums.read_text().splitlines():  # sha256sum format: "<digest>  <name>"
        if line.strip():
            digest, name = line.split(None, 1)
            expected[name.strip().lstrip("*")] = digest
    out = tmp_path_factory.mktemp("conformance")
    for name, digest in expected.items():
        packed = CONFORMANCE_DATA / f"{name}.xz"
        if packed.is_file():
            data = lzma.decompress(packed.read_bytes())
        elif (CONFORMANCE_DATA / name).is_file():
            data = (CONFORMANCE_DATA / name).read_bytes()
        else:
            pytest.fail(f"conformance vector {name} (or {name}.xz) is missing from {CONFORMANCE_DATA}",
                        pytrace=False)
        got = hashlib.sha256(data).hexdigest()
        if got != digest:
            pytest.fail(f"conformance vector {name} from {CONFORMANCE_DATA}: SHA-256 {got}, "
                        f"SHA256SUMS records {digest}", pytrace=False)
        (out / name).write_bytes(data)
    return out
