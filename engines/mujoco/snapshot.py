"""Per-sample copies of several mjData fields in one copy.

The read-out stores about a dozen small mjData arrays at every sample. A
numpy assignment has a fixed cost whatever its size, so copying them one
by one was most of the read-out's Python cost (tests/bench/mujoco_bench.py
times the read-out). mjData keeps its fixed-size arrays
(`MJDATA_POINTERS` in mjxmacro.h, `qpos` first) in one buffer of
`MjData.nbuffer` bytes that does not move for the life of the data, so a
single view of the span that holds the wanted fields, copied once per
sample, takes them all. The span also holds fields nobody wants (several
times the wanted bytes), so it is copied into a small block that is unpacked into
per-field arrays every `CHUNK` samples: memory grows with the wanted fields
only.
"""

from __future__ import annotations

import ctypes

import mujoco
import numpy as np

#: Samples per block (a few MB of span copies at most).
CHUNK = 256


class Snapshot:
    """`take(k)` stores the current values of `fields` (fixed-size float
    mjData arrays) as sample k of n, in order; `fields()` returns them as
    arrays of shape (n,) + field shape once all n are taken."""

    def __init__(self, d: mujoco.MjData, fields: tuple[str, ...], n: int):
        views = {name: getattr(d, name) for name in fields}
        start = min(v.ctypes.data for v in views.values())
        end = max(v.ctypes.data + v.nbytes for v in views.values())
        buffer = d.qpos.ctypes.data
        if (any(v.dtype != np.float64 or (v.ctypes.data - start) % 8 for v in views.values())
                or start < buffer or end > buffer + d.nbuffer):
            raise ValueError(f"mujoco: {fields} are not float arrays of one mjData buffer")
        self.data = d                            # the span is only valid while d lives
        self.span = np.ctypeslib.as_array((ctypes.c_double * ((end - start) // 8)).from_address(start))
        self.layout = {name: ((v.ctypes.data - start) // 8, v.shape) for name, v in views.items()}
        self.n, self.block = n, np.empty((min(n, CHUNK), len(self.span)))
        self.out = {name: np.empty((n,) + v.shape) for name, v in views.items()}

    def take(self, k: int) -> None:
        row = k % len(self.block)
        self.block[row] = self.span
        if row == len(self.block) - 1 or k == self.n - 1:
            self.unpack(k - row, row + 1)

    def unpack(self, first: int, count: int) -> None:
        for name, (offset, shape) in self.layout.items():
            size = int(np.prod(shape))
            self.out[name][first:first + count] = self.block[:count, offset:offset + size].reshape((count,) + shape)

    def fields(self) -> dict[str, np.ndarray]:
        return self.out
