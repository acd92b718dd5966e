"""Which drives a fleet run covers: a folder tree of recordings, or a manifest file.

A folder tree is ``ROOT/<vehicle>/.../<drive>/`` where a drive folder holds a CAN log named as the
daemon's ``--record`` writes it (``can.log``, with ``gnss.log``) or as ``ecu-daemon simulate`` does
(``drive.log``, ``drive_gnss.log``), plus an optional ``truth.csv``. The config is the nearest
``config.toml`` from the drive folder up to the vehicle folder (built-in defaults when there is none).

A manifest is TOML with one ``[[drive]]`` table per drive (paths relative to the manifest)::

    [[drive]]
    vehicle = "car07"
    drive = "2026-12-01-morning"
    config = "car07/config.toml"      # optional
    can = "car07/morning/can.log"
    gnss = ["car07/morning/gnss.log"] # a string or a list; optional
    truth = "car07/morning/truth.csv" # optional
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..errors import UserError

CAN_NAMES = ("can.log", "drive.log")  # --record, simulate
GNSS_NAMES = ("gnss.log", "gnss2.log", "drive_gnss.log", "drive_gnss2.log")  # one per receiver, in order
TRUTH_NAME = "truth.csv"
CONFIG_NAME = "config.toml"


@dataclass(frozen=True)
class Drive:
    vehicle: str
    drive: str
    can: str
    gnss: tuple[str, ...] = ()
    config: str | None = None
    truth: str | None = None
    #: the GNSS latency the replay starts from instead of the config's (learned state, as the
    #: daemon's state_file carries it from one drive to the next); set by ``fleet run --passes 2``
    start_latency_s: float | None = None


def discover(root: str | Path) -> list[Drive]:
    """Every drive folder under ``root`` (see the module doc), sorted by vehicle and drive."""
    root = Path(root)
    drives = []
    for can in sorted(p for name in CAN_NAMES for p in root.rglob(name)):
        folder = can.parent
        rel = folder.relative_to(root).parts
        if not rel:
            raise UserError(f"{can} sits in the fleet root {root}: put each vehicle's drives in ROOT/<vehicle>/")
        gnss = tuple(str(folder / n) for n in GNSS_NAMES if (folder / n).is_file())
        truth = folder / TRUTH_NAME
        drives.append(Drive(vehicle=rel[0], drive="/".join(rel[1:]) or ".", can=str(can), gnss=gnss,
                            config=_nearest_config(folder, root / rel[0]),
                            truth=str(truth) if truth.is_file() else None))
    return _unique(drives, str(root))


def _nearest_config(folder: Path, top: Path) -> str | None:
    d = folder
    while True:
        if (d / CONFIG_NAME).is_file():
            return str(d / CONFIG_NAME)
        if d == top or d == d.parent:
            return None
        d = d.parent


def read_manifest(path: str | Path) -> list[Drive]:
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise UserError(f"cannot read manifest {path}: {getattr(e, 'strerror', None) or e}") from None
    base = path.resolve().parent
    rel = lambda p: str(base / p) if p else None  # noqa: E731
    drives = []
    for i, d in enumerate(doc.get("drive", [])):
        missing = [k for k in ("vehicle", "drive", "can") if not isinstance(d.get(k), str) or not d[k]]
        if missing:
            raise UserError(f"manifest {path}: [[drive]] number {i + 1} lacks {', '.join(missing)}")
        gnss = d.get("gnss", [])
        gnss = [gnss] if isinstance(gnss, str) else list(gnss)
        drives.append(Drive(vehicle=d["vehicle"], drive=d["drive"], can=rel(d["can"]),
                            gnss=tuple(rel(g) for g in gnss), config=rel(d.get("config")), truth=rel(d.get("truth"))))
    return _unique(sorted(drives, key=lambda d: (d.vehicle, d.drive)), str(path))


def load_drives(source: str | Path) -> list[Drive]:
    """A folder (discovered) or a manifest file; at least one drive."""
    p = Path(source)
    if p.is_dir():
        drives = discover(p)
    elif p.is_file():
        drives = read_manifest(p)
    else:
        raise UserError(f"fleet input {p}: no such folder or manifest")
    if not drives:
        raise UserError(f"no drives in {p} (a drive folder holds {' or '.join(CAN_NAMES)})")
    return drives


def _unique(drives: list[Drive], where: str) -> list[Drive]:
    seen = set()
    for d in drives:
        if (d.vehicle, d.drive) in seen:
            raise UserError(f"{where}: drive {d.vehicle}/{d.drive} appears twice")
        seen.add((d.vehicle, d.drive))
    return drives
