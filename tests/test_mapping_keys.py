"""Every key of an import mapping is one calbench reads: a misspelt one (``rollovr``,
``acumulated``) was taken as absent and the import went on without it — wrong numbers without a
word. Each table's keys are checked against what calbench reads (components.logs.mapping.KEYS)
and against docs/import.md, which must hold them all."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from rig_files import mapping

from components.errors import MappingError
from components.logs.logfile import read_log
from components.logs.mapping import load_mapping
from components.logs.mapping_keys import KEYS

DOC = Path(__file__).resolve().parents[1] / "docs" / "import.md"


def test_the_documented_complete_mapping_is_read_and_documents_every_key(tmp_path):
    doc = DOC.read_text()
    block = re.search(r"## A complete mapping\n```toml\n(.*?)```", doc, re.S).group(1)
    (tmp_path / "map.toml").write_text(block)
    load_mapping(tmp_path / "map.toml")
    undocumented = [f"{t}.{k}" for t, keys in KEYS.items() for k in keys
                    if not re.search(rf"(^|[\s\[.`]){k}\b", doc, re.M)]
    assert not undocumented


# (where the typo goes in rig_files.mapping's text, the misspelt key, the error's key and hint)
TYPOS = [
    ("[imu]\n", "descripton = 'x'\n", "key 'descripton'", "description", True),
    ("[imu]\n", "[imu]\nsample_rate = 200\n", "key 'imu.sample_rate'", "sample_rate_hz", False),
    ("[imu.time]\n", "[imu.time]\nrollovr = 65536\n", "key 'imu.time.rollovr'", "rollover", False),
    ("[imu.gyro]\n", "[imu.gyro]\nacumulated = true\n", "key 'imu.gyro.acumulated'", "accumulated", False),
    ("[imu.acc]\n", "[imu.acc]\nrnage = '16 g'\n", "key 'imu.acc.rnage'", "range", False),
    ("[table]\n", "[table]\nencoder_resolutoin = 'exact'\n", "key 'table.encoder_resolutoin'",
     "encoder_resolution", False),
    ("[[table.axes]]\n", "[[table.axes]]\nunti = 'deg'\n", "key 'table.axes[0].unti'", "unit", False),
    ("[site]\n", "[site]\ngravity = 9.8\n", "key 'site.gravity'", "gravity_mps2", False),
]


@pytest.mark.parametrize("anchor, typo, key, hint, before", TYPOS, ids=[t[2] for t in TYPOS])
def test_a_misspelt_key_is_one_error_naming_it_and_the_key_meant(conformance, tmp_path, anchor, typo, key, hint,
                                                                  before):
    text = mapping(read_log(conformance / "example"))
    (tmp_path / "map.toml").write_text(text)
    load_mapping(tmp_path / "map.toml")  # as written, it is read
    assert anchor in text
    (tmp_path / "map.toml").write_text(typo + text if before else text.replace(anchor, typo, 1))
    with pytest.raises(MappingError) as e:
        load_mapping(tmp_path / "map.toml")
    said = str(e.value)
    assert said.startswith(str(tmp_path / "map.toml")) and key in said and f"did you mean '{hint}'" in said, said
