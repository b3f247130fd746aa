"""Read a TOML input file with one clear error: the file missing, or not TOML (with the parser's
line and column), raised as the caller's own error class."""
from __future__ import annotations

import tomllib
from pathlib import Path


def read_toml(path: str | Path, error: type[Exception], kind: str = "", context: str | None = None) -> dict:
    """The parsed table of ``path``. ``kind`` names the file in the missing-file message
    ("scenario" → "scenario file P does not exist"); ``context`` (where the path was given)
    prefixes both messages."""
    p = Path(path)
    head = f"{context}: " if context else ""
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{head}{kind + ' ' if kind else ''}file {p} does not exist") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{head or f'{p}: '}not valid TOML ({e})") from None
