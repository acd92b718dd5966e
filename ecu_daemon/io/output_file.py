"""Output files that never destroy what the user had: checked up front, written aside, renamed.

Why: a replay that opened ``--out-can`` before reading ``--can`` erased the input log when both
named the same file, and a failure half-way left a truncated file under the final name.

* :func:`check_output_paths` refuses, before anything is opened, an output that is one of the
  inputs (same file, also through a link) or another output, a missing directory, a directory.
* :class:`OutputFile` writes a regular-file target to a hidden temporary file in the target's
  directory (so the rename is atomic) whose name ends with the target's name (so the suffix that
  selects a format still does). :meth:`OutputFile.commit` renames it over the target. On a
  failure :meth:`OutputFile.keep_partial` flushes what was written and renames it to
  ``NAME.partial.SUFFIX`` (``out.csv`` -> ``out.partial.csv``); the target is left untouched.
* A target that exists and is not a regular file (``/dev/stdout``, a FIFO, ``/dev/full``) is
  written in place: renaming over a device node would replace the device.
"""
from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path


class OutputPathError(ValueError):
    """An output path that cannot or must not be written; the message is one line for the user."""


def _identity(path: Path) -> tuple:
    """What makes two paths the same file: (device, inode) when it exists, else the resolved path."""
    try:
        st = os.stat(path)
    except OSError:
        return ("path", str(path.resolve()))
    return ("inode", st.st_dev, st.st_ino)


def check_output_paths(outputs: dict[str, str | None], inputs: dict[str, str | None]) -> None:
    """Raise :class:`OutputPathError` for an output that would overwrite an input or another output,
    or that cannot be created (missing directory, a directory). Keys are the option names."""
    seen: dict[tuple, str] = {}
    for what, p in inputs.items():
        if p is not None:
            seen.setdefault(_identity(Path(p)), what)
    for what, p in outputs.items():
        if p is None:
            continue
        path = Path(p)
        ident = _identity(path)
        if ident in seen:
            raise OutputPathError(f"{what} {p} is the same file as {seen[ident]}: refusing to overwrite it")
        if path.is_dir():
            raise OutputPathError(f"{what} {p} is a directory; give a file name")
        parent = path.parent
        if not parent.is_dir():
            raise OutputPathError(f"{what} {p}: directory {parent} does not exist")
        seen[ident] = what


def partial_name(path: Path) -> Path:
    """``out.csv`` -> ``out.partial.csv``, ``drive.log.gz`` -> ``drive.partial.log.gz``."""
    stem, dot, suffixes = path.name.partition(".")
    if not stem:  # a hidden file such as ".out"
        return path.with_name(path.name + ".partial")
    return path.with_name(f"{stem}.partial{dot}{suffixes}")


class OutputFile:
    """One output written aside and renamed into place at :meth:`commit` (see the module doc).

    ``write_path`` is where the writer should write (a temporary file, or the target itself for a
    device or pipe). Use :meth:`open` for a text file, or hand ``write_path`` to a writer that
    opens files itself and call :meth:`commit` / :meth:`keep_partial` after closing it.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.in_place = self.path.exists() and not stat.S_ISREG(os.stat(self.path).st_mode)
        if self.in_place:
            self.write_path = self.path
        else:
            tmp = self.path.with_name(f".partial-{secrets.token_hex(4)}-{self.path.name}")
            try:  # O_EXCL: never another file; mode 0666 & ~umask, as open() would give the target
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            except OSError as e:
                raise OutputPathError(f"cannot write {self.path}: {e.strerror or e}") from None
            self.write_path = tmp
        self.file = None
        self.finished = False

    def open(self):
        """A text file on :attr:`write_path` (ASCII, ``\\n`` line ends)."""
        try:
            self.file = open(self.write_path, "w", encoding="ascii", newline="\n")
        except OSError as e:
            raise OutputPathError(f"cannot write {self.path}: {e.strerror or e}") from None
        return self.file

    def _close(self) -> OSError | None:
        f, self.file = self.file, None
        if f is None:
            return None
        try:
            f.close()
        except OSError as e:
            try:  # close() flushes first and keeps the buffer when the flush fails: drop it
                f.close()
            except OSError:
                pass
            return e
        return None

    def commit(self) -> None:
        """Close and move the finished file into place; raises OutputPathError if that fails."""
        err = self._close()
        self.finished = True
        if err is not None:
            self.finished = False
            self.keep_partial()
            raise OutputPathError(f"cannot write {self.path}: {err.strerror or err}")
        if not self.in_place:
            os.replace(self.write_path, self.path)

    def keep_partial(self) -> Path | None:
        """After a failure: close (flushing what it can) and keep the partial file beside the target.

        Returns where it is kept, or None when nothing was kept (written in place, or empty)."""
        self._close()
        if self.in_place or self.finished:
            return None
        self.finished = True
        try:
            if os.path.getsize(self.write_path) == 0:
                os.unlink(self.write_path)
                return None
            dest = partial_name(self.path)
            os.replace(self.write_path, dest)
            return dest
        except OSError:
            return None
