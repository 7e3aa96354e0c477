"""Per-sample copies of several mjData fields in one copy.

The read-out stores about a dozen small mjData arrays at every sample. A
numpy assignment costs about a microsecond whatever its size, so copying
them one by one was most of the read-out's Python cost (a quarter of the
adapter's overhead on a 400-sample run). mjData keeps its fixed-size arrays
(the `MJDATA_POINTERS` of mjdata.h) in one buffer that does not move for the
life of the data, so the fields lie within one span of at most
`MjModel.nbuffer` bytes: a single view of that span, copied once per
sample, holds them all at fixed offsets.
"""

from __future__ import annotations

import ctypes

import mujoco
import numpy as np


class Snapshot:
    """`take(k)` stores the current values of `fields` (fixed-size float
    mjData arrays) as sample k of n; `fields()` returns them as arrays of
    shape (n,) + field shape."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, fields: tuple[str, ...], n: int):
        views = {name: getattr(d, name) for name in fields}
        start = min(v.ctypes.data for v in views.values())
        end = max(v.ctypes.data + v.nbytes for v in views.values())
        if (any(v.dtype != np.float64 or (v.ctypes.data - start) % 8 for v in views.values())
                or end - start > m.nbuffer):
            raise ValueError(f"mujoco: {fields} are not float arrays of one mjData buffer")
        self.data = d                            # the span is only valid while d lives
        self.span = np.ctypeslib.as_array((ctypes.c_double * ((end - start) // 8)).from_address(start))
        self.layout = {name: ((v.ctypes.data - start) // 8, v.shape) for name, v in views.items()}
        self.rows = np.empty((n, len(self.span)))

    def take(self, k: int) -> None:
        self.rows[k] = self.span

    def fields(self) -> dict[str, np.ndarray]:
        n = len(self.rows)
        return {name: self.rows[:, offset:offset + int(np.prod(shape))].reshape((n,) + shape)
                for name, (offset, shape) in self.layout.items()}
