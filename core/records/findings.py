"""Engine findings: known misbehaviour of an engine, measured on the
installed version.

A `Finding` says what is wrong with one of an engine's read-outs, how a
probe measures it and which versions are known to have it. A probe (in
`mechval.engines`, next to the adapter: it needs the engine) builds a tiny
model, compares the read-out with the exact value of the engine's own state
and returns a `Measurement`. The harness runs the probes and hands the
measurements to the report, which therefore never imports an engine.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Finding:
    """A known misbehaviour of one engine read-out."""

    key: str            # stable identifier, e.g. "pybullet.slide-sensor-turning-parent"
    engine: str
    title: str
    wrong: str          # what is wrong and what it costs a user
    how: str            # how the probe measures it (model, exact value)
    figure: str         # what the measured figure is, e.g. "|N read − N exact| / |N exact|"
    #: The figure above which the finding is present; a correct read-out
    #: stays below it by orders of magnitude (the probe's test shows that
    #: the exact value is right).
    present_above: float
    since: str          # first version known to have it (measured or cited)
    until: str = ""     # first version known to be fixed; "" = not fixed
    workaround: str = ""


@dataclass(frozen=True)
class Measurement:
    """A probe's result on the installed engine version."""

    finding: Finding
    version: str
    figure: float = float("nan")
    read: float = float("nan")      # the engine's read-out
    exact: float = float("nan")     # the exact value for the engine's own state
    error: str = ""                 # why the probe could not measure

    @property
    def present(self) -> bool:
        return not self.error and self.figure > self.finding.present_above

    @property
    def status(self) -> str:
        if self.error:
            return f"not measured: {self.error}"
        return "present" if self.present else "not present (fixed in this version?)"

    def describe(self) -> str:
        """The measured figure in words, e.g. "0.5 (read 1.07, exact 0.713)"."""
        if self.error:
            return "—"
        return f"{self.figure:.3g} (read {self.read:.6g}, exact {self.exact:.6g})"
