"""DBC file -> cantools database, the one way every command loads one.

* **IMPORT lines.** opendbc's generator sources include other files with ``CM_ "IMPORT
  _file.dbc";`` lines, which opendbc's ``generator.py`` resolves into the flat DBCs it ships.
  cantools reads them as plain comments, so such a file would load with only its own messages,
  the imported ones missing, without a word. Here they are resolved as the generator does: the
  imported files' text first (relative to the importing file's folder, each at most once,
  imports of imports too), then the file's own; a missing import is an error naming both files.
* **strict, then not.** Real production DBCs (opendbc's) often fail cantools' strict checks
  (overlapping signals, values outside their range); they are loaded with ``strict=False``
  and ONE info line saying why, the same line whichever command loads them.
"""
from __future__ import annotations

import hashlib
import logging
import pickle
import re
from collections import OrderedDict
from pathlib import Path
from typing import NamedTuple

import cantools
import cantools.database

from .config import ConfigError

log = logging.getLogger(__name__)

_IMPORT = re.compile(r'^[ \t]*CM_[ \t]+"IMPORT[ \t]+([^"]+?)"[ \t]*;[ \t]*\r?$', re.M)
#: ``CM_ SG_ 304 "text";``: a message comment tagged as a signal one (opendbc's _honda_common.dbc, so
#: every Honda DBC); cantools rejects the whole file for it
_SIGNAL_COMMENT_WITHOUT_SIGNAL = re.compile(r'^([ \t]*CM_[ \t]+)SG_([ \t]+\d+[ \t]+")', re.M)
#: a frame id in a statement that names a message; above 0x7FF without the DBC's extended-id bit 31,
#: opendbc means a 29-bit id (Honda's LKAS_HUD_A 13274), which cantools refuses
_MESSAGE_ID = re.compile(r'^([ \t]*(?:BO_|VAL_|SIG_VALTYPE_|SG_MUL_VAL_|BO_TX_BU_|CM_[ \t]+(?:BO_|SG_)'
                         r'|BA_[ \t]+"[^"]*"[ \t]+(?:BO_|SG_))[ \t]+)(\d+)\b', re.M)
_DBC_EXTENDED = 0x80000000
_LINE_IN_ERROR = re.compile(r"\bline (\d+)(, column \d+)?")
#: cantools' default encoding for DBC files
ENCODING = "cp1252"


class DbcText:
    """A DBC's text with its IMPORT lines resolved, and where each line came from."""

    def __init__(self, path: Path, what: str = "DBC"):
        self.path = Path(path)
        self.what = what
        self.parts: list[tuple[Path, str]] = []  # (file, its own text with IMPORT lines blanked), in order
        self._seen = {self.path.resolve()}
        self._add(self.path, None)
        self.imported = [p for p, _ in self.parts[:-1]]
        self.text = "\n".join(t for _, t in self.parts)

    def _add(self, p: Path, importer: Path | None) -> None:
        try:
            text = p.read_text(encoding=ENCODING, errors="replace")
        except OSError as e:
            if importer is None:
                raise ConfigError(f"{self.what}: cannot read {p}: {e.strerror or e}") from None
            raise ConfigError(f"{self.what}: {importer} imports {p.name}, which cannot be read"
                              f" ({e.strerror or e}; looked in {p.parent})") from None
        for name in _IMPORT.findall(text):
            dep = (p.parent / name.strip()).resolve()
            if dep not in self._seen:
                self._seen.add(dep)
                self._add(dep, p)
        self.parts.append((p, _IMPORT.sub("", text)))

    def where(self, line: int) -> tuple[Path, int]:
        """File and line number of a line of :attr:`text`."""
        first = 1
        for p, t in self.parts:
            n = t.count("\n") + 1
            if line < first + n:
                return p, line - first + 1
            first += n
        return self.path, line

    def explain(self, error: Exception) -> str:
        """cantools' parse error with the line number turned into the file it is in."""
        text = str(error)
        m = _LINE_IN_ERROR.search(text)
        if not m or not self.imported:
            return text
        p, n = self.where(int(m.group(1)))
        return text[:m.start()] + f"line {n}{m.group(2) or ''} of {p.name}" + text[m.end():]


def _opendbc_dialect(text: str) -> tuple[str, int, set[int]]:
    """Read two things opendbc's own parser accepts and cantools does not: the text cantools
    gets, the count of signal-less signal comments and the 29-bit ids given as plain numbers
    (each said in one line by :func:`_say_dialect`)."""
    text, n = _SIGNAL_COMMENT_WITHOUT_SIGNAL.subn(r"\1BO_\2", text)
    extended: set[int] = set()

    def mark(m: re.Match) -> str:
        fid = int(m.group(2))
        if 0x7FF < fid < _DBC_EXTENDED:
            extended.add(fid)
            fid |= _DBC_EXTENDED
        return f"{m.group(1)}{fid}"

    return _MESSAGE_ID.sub(mark, text), n, extended


def _say_dialect(what: str, path: Path, n: int, extended: set[int]) -> None:
    if n:
        log.info("%s: %s has %d 'CM_ SG_ <id> \"...\"' comment(s) without a signal name; read as message"
                 " comments", what, path, n)
    if extended:
        log.info("%s: %s gives %s as plain numbers above 0x7FF; read as 29-bit ids, as opendbc does", what,
                 path, ", ".join(f"0x{f:X}" for f in sorted(extended)))


class _Parsed(NamedTuple):
    blob: bytes | None  # the database pickled (None: it does not pickle, not cached)
    comments: int
    extended: set[int]
    strict_error: str | None  # why strict loading failed (loaded with strict=False)


#: parsed DBCs by the SHA-256 of their text (IMPORTs resolved) and the strictness asked for,
#: most recent last: a fleet replays hundreds of drives of a few vehicles in one process, and
#: parsing took ~20 ms of each drive's start-up (unpickling a copy: ~1.5 ms). A changed file
#: (or one of its imports) has another hash, so it is parsed again; every caller gets its own
#: copy (nothing parsed is shared).
_CACHE: OrderedDict[tuple[bytes, bool], _Parsed] = OrderedDict()
CACHE_SIZE = 32


def load_dbc(path: Path, what: str = "[can] dbc", allow_non_strict: bool = True):
    """Load a DBC with ``strict=True``; real production DBCs (opendbc) need ``strict=False``.

    IMPORT lines are resolved (see module doc). Falls back to non-strict loading with ONE info
    line when allowed. Any failure to read or parse becomes a :class:`ConfigError` naming the file.
    A text parsed before in this process is not parsed again (:data:`_CACHE`); the lines said
    about it are said again.
    """
    path = Path(path)
    dbc = DbcText(path, what)
    if dbc.imported:
        log.info("%s: %s imports %s (opendbc IMPORT lines); loaded them with it", what, path,
                 ", ".join(p.name for p in dbc.imported))
    key = (hashlib.sha256(dbc.text.encode("utf-8", "surrogatepass")).digest(), allow_non_strict)
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        _say(what, path, hit)
        return pickle.loads(hit.blob)
    db, parsed = _parse(dbc, what, path, allow_non_strict)
    if parsed.blob is not None:
        _CACHE[key] = parsed
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    _say(what, path, parsed)
    return db


def _say(what: str, path: Path, parsed: _Parsed) -> None:
    _say_dialect(what, path, parsed.comments, parsed.extended)
    if parsed.strict_error is not None:
        log.info("%s: %s fails cantools' strict checks (%s); loaded it with strict=False",
                 what, path, parsed.strict_error)


def _parse(dbc: DbcText, what: str, path: Path, allow_non_strict: bool):
    text, comments, extended = _opendbc_dialect(dbc.text)

    def load(strict: bool):
        return cantools.database.load_string(text, database_format="dbc", strict=strict)

    strict_error = None
    try:
        db = load(True)
    except Exception as e:  # cantools raises several types for a file it rejects
        if not allow_non_strict:
            _say_dialect(what, path, comments, extended)
            raise ConfigError(f"{what}: {path} is not a valid DBC: {dbc.explain(e)}") from None
        strict_error = str(e)
        try:
            db = load(False)
        except Exception as e2:
            _say_dialect(what, path, comments, extended)
            raise ConfigError(f"{what}: {path} is not a valid DBC: {dbc.explain(e2)}") from None
    try:
        blob = pickle.dumps(db, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # a database that does not pickle is just not cached
        blob = None
    return db, _Parsed(blob, comments, extended, strict_error)
