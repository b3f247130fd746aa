"""The campaign's output folder.

::

    OUT/cases/<case id>.json   one record per finished case, written at once (tmp + os.replace)
    OUT/manifest.json          hashes, versions, seeds, host, and the start/end of every session
    OUT/.runs/                 one marker file per case execution (a case process touches it)
    OUT/summary.json, junit.xml, report.html, pages/   the reports

A record is only ever complete or absent: a killed campaign leaves no half file, and
``--resume`` runs exactly the cases without one."""
from __future__ import annotations

import json
import os
from pathlib import Path


def atomic_write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        # a SIGTERM is raised in the main thread wherever it lands (components.campaign.execute),
        # also between the write and the rename (the fsync waits on the disk): no half file, and
        # no temporary one left in the cases folder either
        tmp.unlink(missing_ok=True)
        raise
    return path


class Store:
    def __init__(self, out: str | Path):
        self.out = Path(out)
        self.cases_dir = self.out / "cases"
        self.runs_dir = self.out / ".runs"

    def prepare(self) -> None:
        self.cases_dir.mkdir(parents=True, exist_ok=True)
        self.runs_dir.mkdir(parents=True, exist_ok=True)

    def case_path(self, case_id: str) -> Path:
        return self.cases_dir / f"{case_id}.json"

    def write_case(self, record: dict, text: str) -> Path:
        return atomic_write(self.case_path(record["id"]), text)

    def done(self) -> set[str]:
        """Ids of the cases with a complete record."""
        if not self.cases_dir.is_dir():
            return set()
        out = set()
        for p in self.cases_dir.glob("*.json"):
            try:
                json.loads(p.read_text())
            except (OSError, json.JSONDecodeError):
                continue   # cannot happen with atomic writes; rerun it if it does
            out.add(p.stem)
        return out

    def records(self, ids) -> list[dict]:
        return [json.loads(self.case_path(i).read_text()) for i in sorted(ids) if self.case_path(i).exists()]

    def runs(self) -> dict[str, int]:
        """Case id -> how many times a case process started it (markers)."""
        out: dict[str, int] = {}
        if self.runs_dir.is_dir():
            for p in self.runs_dir.iterdir():
                cid = p.name.split(".", 1)[0]
                out[cid] = out.get(cid, 0) + 1
        return out

    @property
    def manifest_path(self) -> Path:
        return self.out / "manifest.json"

    def read_manifest(self) -> dict | None:
        try:
            return json.loads(self.manifest_path.read_text())
        except (OSError, json.JSONDecodeError):
            return None

    def write_manifest(self, manifest: dict) -> None:
        atomic_write(self.manifest_path, json.dumps(manifest, indent=1, sort_keys=True) + "\n")
