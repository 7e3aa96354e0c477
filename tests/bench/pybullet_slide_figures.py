"""Figures: PyBullet's slide reaction read from its sensor against the one
the adapter derives from the sliding body's balance, on the built-in slide
scenes and the user-like variants of tests/test_linkages_more.py (offset,
rod centre of mass away from A, dampers), at the default step and at finer
ones.

    .venv/bin/python tests/bench/pybullet_slide_figures.py [--steps] [SCENE ...]

Per scene and step: the ratio max error / default bound of F43x, F43y,
N43, M43 (≤ 1 passes), sensor → derived, and the worst other force or
torque ratio (the derivation leaves those bit-identical). `--steps` adds
the default step / 2 and / 4. Prints figures; asserts nothing.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mechval.judging.compare import compare  # noqa: E402
from mechval.engines.pybullet import run as adapter_module  # noqa: E402
from mechval.engines.registry import adapter  # noqa: E402
from mechval.reference.linkages import build_mechanism  # noqa: E402
from mechval.harness.simulate import simulate
from test_linkages_more import SCENES  # noqa: E402

SLIDE = ("F43x", "F43y", "N43", "M43")


def ratios(scenario, overrides, sensor: bool):
    """Ratio per signal against the scenario's own (default) tolerances;
    `sensor` skips the derivation, leaving the sensor's reading."""
    derive = adapter_module.Stepper.derived_reactions
    if sensor:
        adapter_module.Stepper.derived_reactions = lambda self, *args: {}
    try:
        result = simulate(scenario, adapter("pybullet"), overrides)
    finally:
        adapter_module.Stepper.derived_reactions = derive
    records = compare(simulate(scenario, "reference"), result, scenario.tolerance, scenario=scenario.name)
    records = records[records["class"].isin(["force", "torque"])].set_index("signal")["ratio"]
    return records, result.info.facts["timestep_used"]


def main(argv: list[str]) -> None:
    steps = "--steps" in argv
    names = [a for a in argv if not a.startswith("--")] or list(SCENES)
    print(f"{'scene':<20} {'dt':>9}  " + "  ".join(f"{s:>16}" for s in SLIDE) + "  worst other")
    for name in names:
        scenario = SCENES[name]
        base = adapter("pybullet").settings_for(scenario, build_mechanism(scenario))["timestep"]
        for k in ((1, 2, 4) if steps else (1,)):
            overrides = {"timestep": base / k} if k > 1 else None
            read, dt = ratios(scenario, overrides, sensor=True)
            derived, _ = ratios(scenario, overrides, sensor=False)
            cells = "  ".join(f"{read[s]:>7.3g} → {derived[s]:<6.2g}" for s in SLIDE)
            print(f"{name:<20} {dt:>9.3g}  {cells}  {derived.drop(list(SLIDE)).max():.3g}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
