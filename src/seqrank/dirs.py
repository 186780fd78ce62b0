"""Output paths checked before anything is written, and one process per directory.

`check_folder` and `check_file` refuse an output path that cannot be used (a file where a
folder is wanted, a folder where a file is, a parent that is a file or not writable) with
one line naming it, before a command writes anything.

`DirLock` holds an exclusive `flock` on `<folder>/.lock`, a file that holds the pid of the
process that holds it. A second process that takes the same folder (a second `seqrank
label` on a labelling directory, a `seqrank train --resume` of a run that is training) is
refused with a message naming the holder. The kernel drops the lock when its process ends,
however it ends, so the lock of a killed process is simply taken over; the file stays.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path
from types import TracebackType

LOCK_NAME = ".lock"


class DirectoryInUse(ValueError):
    """Another process holds the folder's lock."""


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if candidate.exists():
            return candidate
    return Path(".")


def _check_parents(path: Path, what: str) -> None:
    existing = _nearest_existing(path.parent)
    if not existing.is_dir():
        raise ValueError(f"{what} {path}: {existing} is a file, not a folder; choose another path")
    if not path.exists() and not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {path}: {existing} is not writable; choose another path")


def check_folder(path: Path, what: str) -> None:
    """ValueError unless `path` is a folder or can be made one (nothing is written)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path} is a file, not a folder; choose a folder path")
    _check_parents(path, what)


def check_file(path: Path, what: str) -> None:
    """ValueError unless `path` is a file or can be written as one (nothing is written)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {path} is a folder; give a file path")
    _check_parents(path, what)


def missing_folders(path: Path) -> list[Path]:
    """The folders of `path` (itself included) that do not exist yet, outermost first."""
    path = Path(path)
    return [p for p in reversed((path, *path.parents)) if not p.exists()]


def remove_made(folders: list[Path]) -> None:
    """Remove folders made by a command that failed, innermost first, where they are empty."""
    for folder in reversed(folders):
        with contextlib.suppress(OSError):
            folder.rmdir()


class DirLock:
    """An exclusive lock on a folder for as long as this process holds it (see module doc)."""

    def __init__(self, folder: Path, what: str):
        self.folder, self.what = Path(folder), what
        self._fd: int | None = None

    @property
    def path(self) -> Path:
        return self.folder / LOCK_NAME

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> None:
        """Take the lock (the folder must exist); DirectoryInUse names the holder."""
        if self._fd is not None:
            return
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise DirectoryInUse(
                f"{self.what} {self.folder} is in use by another seqrank process (pid "
                f"{holder}); one process per directory: wait for it to end, or stop it"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        if self._fd is None:
            return
        fcntl.flock(self._fd, fcntl.LOCK_UN)
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> DirLock:
        self.acquire()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.release()
