"""Per-drive results on disk, one JSON file per drive, named by the drive's content key.

A result appears whole or not at all (written aside, then renamed), so an interrupted run leaves
only finished drives behind and the next run skips exactly those.
"""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path


class ResultStore:
    def __init__(self, directory: str | Path):
        self.dir = Path(directory)

    def path(self, key: str) -> Path:
        return self.dir / key[:2] / f"{key}.json"

    def load(self, key: str) -> dict | None:
        """The stored result, or None when there is none (or it cannot be read: redo it)."""
        try:
            return json.loads(self.path(key).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None

    def save(self, key: str, record: dict) -> None:
        p = self.path(key)
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{key}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(record, f, sort_keys=True)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, p)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
