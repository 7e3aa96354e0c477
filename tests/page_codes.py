"""The report page's decoding of its figure data (reports/templates/report.js,
`codeStream` and `unpack`), transcribed to Python so that tests can read
back what `mechval.reports.plots` encodes, as the browser does."""

from __future__ import annotations

import base64
import zlib

import numpy as np


def decode_stream(text: str) -> np.ndarray:
    """codeStream: inflate, low and high byte planes, running sum modulo
    2¹⁶ (uint16 codes)."""
    planes = np.frombuffer(zlib.decompress(base64.b64decode(text)), dtype=np.uint8)
    low, high = planes[:len(planes) // 2].astype(np.uint16), planes[len(planes) // 2:].astype(np.uint16)
    return np.cumsum(low | (high << 8), dtype=np.uint16)


def linear_values(codes: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """unpack of an entry with `lin`: 65535 is NaN, else lo + code·(hi − lo)/65534."""
    return np.where(codes == 65535, np.nan, lo + codes * ((hi - lo) / 65534))


def log_values(codes: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """unpack of an entry with `log`: the codes as int16; −32768 is NaN, 0
    is zero, else sign(c)·10^(lo + (|c| − 1)·(hi − lo)/32766)."""
    codes = codes.astype(np.int16)
    magnitude = 10.0 ** (lo + (np.abs(codes.astype(float)) - 1) * ((hi - lo) / 32766))
    return np.where(codes == -32768, np.nan, np.where(codes == 0, 0.0, np.sign(codes) * magnitude))
