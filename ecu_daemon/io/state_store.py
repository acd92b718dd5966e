"""Persist the estimator's learned quantities so a restart or a crash does not lose them.

Atomic by construction: write a temporary file in the same directory, fsync it, rename it over
the old one, fsync the directory. A reader therefore sees either the old or the new file, never
half of one. A missing file is normal (first start); an unreadable or corrupt one is reported in
one line by the caller and ignored, so the estimator simply starts from its priors.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

FORMAT = "ecu-daemon-state"
VERSION = 1


class StateFileError(Exception):
    """The state file exists but cannot be used (message is one line)."""


def _finite_only(obj):
    """JSON has no NaN/inf; drop them rather than write a file the next start rejects."""
    if isinstance(obj, dict):
        return {k: _finite_only(v) for k, v in obj.items()
                if not (isinstance(v, float) and not math.isfinite(v))}
    if isinstance(obj, (list, tuple)):
        return [_finite_only(v) for v in obj]
    return obj


def save_state(path: str | Path, learned: dict, saved_at: float | None = None) -> None:
    """Write ``learned`` atomically; raises OSError on failure (caller logs one line)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    doc = {"format": FORMAT, "version": VERSION, "learned": _finite_only(learned)}
    if saved_at is not None:
        doc["saved_at_unix_s"] = saved_at
    data = json.dumps(doc, indent=1, sort_keys=True).encode() + b"\n"
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    try:
        dfd = os.open(p.parent, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass  # some filesystems refuse directory fsync; the rename is still atomic


def load_state(path: str | Path) -> dict | None:
    """Return the learned dict, ``None`` if there is no file, or raise :class:`StateFileError`."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as e:
        raise StateFileError(f"cannot read state file {p}: {e.strerror or e}") from None
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise StateFileError(f"state file {p} is corrupt ({e.__class__.__name__}: {e})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("learned"), dict):
        raise StateFileError(f"state file {p} is not an ecu-daemon state file")
    if doc.get("version") != VERSION:
        raise StateFileError(f"state file {p} has unsupported version {doc.get('version')!r}")
    return doc["learned"]
