"""How the spatial reference's loops are compiled: numba, cached beside
each module (only the first process compiles), releasing the GIL (the
batches run in threads), with numpy's error model: a float division by
zero gives IEEE's inf or nan instead of a check and an exception, so
loops that divide compile to vector instructions (each result rounds as
before; no kernel divides by a zero it has not tested for).

numba keys a function's cache on its own file alone, but the kernels
call, and inline, each other across files (`chord` holds `lu`'s LU and
`assembly`'s rows): after a change to one of them (an edit, a pull) the
others' cached code would still run the old one. So the cache beside
these modules is dropped whenever any kernel file differs from the one
it was compiled from (`drop_stale_cache`, at import, before any kernel
is defined).
"""

import hashlib
from pathlib import Path

import numba

HERE = Path(__file__).parent
#: Beside the modules: the digest of the kernel files the cache was compiled from.
STAMP = HERE / "__pycache__" / "kernels.sha256"


def kernel_sources() -> list[Path]:
    """This package's files that define kernels, and this one."""
    return sorted(p for p in HERE.glob("*.py")
                  if p.name == "kernel.py" or "@kernel" in p.read_text("utf-8").splitlines())


def drop_stale_cache() -> None:
    """Remove numba's cache files beside these modules unless STAMP holds
    the digest of today's kernel files; then write it. Where the folder is
    not writable numba caches elsewhere (its user-wide folder, keyed by
    each file as before) and nothing is done."""
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in kernel_sources())).hexdigest()
    try:
        if STAMP.read_text("utf-8") == digest:
            return
    except OSError:
        pass
    try:
        STAMP.parent.mkdir(exist_ok=True)
        for cached in STAMP.parent.glob("*.nb[ic]"):
            cached.unlink(missing_ok=True)
        STAMP.write_text(digest, "utf-8")
    except OSError:
        pass


drop_stale_cache()
kernel = numba.njit(cache=True, nogil=True, error_model="numpy")
