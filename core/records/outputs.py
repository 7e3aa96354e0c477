"""Output files and folders, written whole or not at all, and only where
the user said (docs/comparison.md, "Output files").

A file is written to a temporary sibling and renamed over its path; a
report folder is filled as a temporary sibling folder and renamed into
place. A rename replaces whatever its target is, so a target that exists
and is not a regular file (a device such as /dev/full, a FIFO, a symlink,
a folder) is refused rather than replaced. An error is reported with the
path the user named, never the temporary one.

A temporary folder is named `.OUT.XXXXXXXX.mechval-partial` and holds an
exclusive flock(2) for as long as its writer lives: the kernel releases
the lock when the writer ends, SIGKILL included. The next write into the
same parent removes such folders whose lock is free and that have not
changed for STALE_AFTER_S seconds (the lock is taken a moment after the
folder is made); nothing else is touched.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import stat
import tempfile
import time
from pathlib import Path

#: The end of a temporary report folder's name (module docstring).
PARTIAL_SUFFIX = ".mechval-partial"
#: Seconds a temporary folder must have been left alone before it counts
#: as stale: far more than its writer takes from making it to locking it.
STALE_AFTER_S = 10.0

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISLNK, "a symlink"), (stat.S_ISFIFO, "a FIFO"),
          (stat.S_ISCHR, "a device"), (stat.S_ISBLK, "a device"), (stat.S_ISSOCK, "a socket"))


def not_a_regular_file(path: str | os.PathLike) -> str:
    """What `path` is when it exists and is not a regular file ("a FIFO",
    "a symlink", …; a symlink is not followed), else ""."""
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):     # nothing there to replace
        return ""
    if stat.S_ISREG(mode):
        return ""
    return next((kind for test, kind in _KINDS if test(mode)), "not a regular file")


def refuse_non_regular(path: str | os.PathLike) -> None:
    """Raise an OSError naming `path` when it exists and is not a regular file."""
    kind = not_a_regular_file(path)
    if kind:
        raise FileExistsError(errno.EEXIST, f"it is {kind}, and mechval replaces only regular files", str(path))


def _naming(exc: OSError, path: Path, tmp: Path) -> OSError:
    """`exc` naming `path` instead of the temporary `tmp` (or of nothing,
    as a full disk's error does)."""
    named = Path(exc.filename) if exc.filename else tmp
    try:
        shown = path / named.relative_to(tmp) if named != tmp else path
    except ValueError:
        return exc                       # about another file: as it stands
    return type(exc)(exc.errno, exc.strerror or str(exc), str(shown))


def write_atomically(path: str | os.PathLike, write) -> None:
    """Call write(file) on a temporary sibling of path, then rename it."""
    path = Path(path)
    refuse_non_regular(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="") as f:
            os.fchmod(fd, 0o666 & ~current_umask())  # mkstemp's 0600, as a plain open would make it
            write(f)
        refuse_non_regular(path)         # made meanwhile
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise _naming(exc, path, Path(tmp)) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_folder_atomically(out: str | os.PathLike, fill) -> Path:
    """Call fill(folder) on a temporary sibling of `out` (which must not
    exist yet), then rename it to `out`: an interrupted write leaves nothing
    (a killed one leaves a folder the next write removes)."""
    out = Path(out)
    if os.path.lexists(out):
        raise FileExistsError(f"{out} exists; choose another --out or remove it")
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(out.parent)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=PARTIAL_SUFFIX, dir=out.parent))
    lock = os.open(tmp, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        os.chmod(tmp, 0o777 & ~current_umask())     # mkdtemp's 0700, as a plain mkdir would make it
        fill(tmp)
        # A rename onto a folder that another command has just written
        # fails naming the temporary folder: say what happened instead.
        if os.path.lexists(out):
            raise FileExistsError(errno.EEXIST, "written meanwhile by another command", str(out))
        os.replace(tmp, out)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if not isinstance(exc, OSError):
            raise
        if os.path.lexists(out):
            raise FileExistsError(f"{out} exists (written meanwhile by another command); choose another "
                                  "--out or remove it") from None
        raise _naming(exc, out, tmp) from None
    finally:
        os.close(lock)
    return out


def remove_stale_partials(parent: Path) -> list[Path]:
    """Remove, from `parent`, the temporary folders of report writers that
    were killed (module docstring); return them."""
    removed = []
    now = time.time()
    for candidate in parent.glob(f".*{PARTIAL_SUFFIX}"):
        with contextlib.suppress(OSError):
            info = os.lstat(candidate)
            if (not stat.S_ISDIR(info.st_mode) or info.st_uid != os.geteuid()
                    or now - info.st_mtime < STALE_AFTER_S):
                continue
            fd = os.open(candidate, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)     # fails while its writer lives
                shutil.rmtree(candidate)
                removed.append(candidate)
            finally:
                os.close(fd)
    return removed


def current_umask() -> int:
    """The process's umask (reading it means setting it: restored at once)."""
    mask = os.umask(0o077)
    os.umask(mask)
    return mask
