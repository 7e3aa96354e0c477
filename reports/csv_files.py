"""The report folders' CSV files (discrepancies.csv, cost.csv,
convergence.csv, cheapest.csv), safe to open in a spreadsheet.

Numbers are written at full precision (%.17g), NaN as an empty cell. A text
cell that a spreadsheet would read as a formula — one that starts with =,
+, -, @, a tab or a carriage return, e.g. a scenario named
`=HYPERLINK(…)` — is written with a leading apostrophe, which spreadsheets
show as text (OWASP, "CSV Injection"). Only text cells change: numbers,
negative ones included, stay numbers (docs/comparison.md, "Output files").
Lines end in CRLF (RFC 4180): Python's csv writer quotes a cell holding a
character of the line ending, so a carriage return inside a text cell
cannot start a new row whose first cell escaped the rule above.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

#: What a spreadsheet takes for the start of a formula.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def neutralised(cell):
    """`cell` with an apostrophe in front if it is text a spreadsheet would
    read as a formula; anything else as it is."""
    return "'" + cell if isinstance(cell, str) and cell.startswith(FORMULA_STARTS) else cell


def spreadsheet_safe(frame: pd.DataFrame) -> pd.DataFrame:
    """A copy of `frame` whose text cells are neutralised (module docstring)."""
    text = [c for c in frame.columns if not pd.api.types.is_numeric_dtype(frame[c])]
    return frame.assign(**{c: frame[c].map(neutralised) for c in text}) if text else frame


def write_csv(frame: pd.DataFrame, path: Path) -> None:
    """`frame` as a spreadsheet-safe CSV file: full precision, NaN empty."""
    spreadsheet_safe(frame).to_csv(path, index=False, float_format="%.17g", na_rep="", lineterminator="\r\n")
