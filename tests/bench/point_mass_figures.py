"""Figures for point masses that turn with another body (izz = 0): the
README's number form of the slotted lever's block and of the hand pump's
sleeve, each engine against the reference (largest error per signal
class, relative to peak; angles and positions absolute), and MuJoCo's
inverse mode, where only rounding should separate it from the reference,
on the block at full and at millimetre-and-gram scale. Asserts nothing.

    .venv/bin/python tests/bench/point_mass_figures.py
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from test_engines import POINT_MASS_SCENES  # noqa: E402

from mechval.judging.compare import compare  # noqa: E402
from mechval.engines.registry import EngineUnavailable, adapter, engine_names  # noqa: E402
from mechval.scenarios import parse  # noqa: E402
from mechval.harness.simulate import simulate
from mechval.testing.scenes import merge  # noqa: E402


def worst_by_class(records) -> str:
    records = records[records["class"] != "health"].copy()
    absolute = records["class"].isin(["angle", "position"])
    records["error"] = records["relative_error"].where(~absolute, records["max_error"])
    worst = records.groupby("class")["error"].max()
    return "  ".join(f"{cls} {value:.2g}" for cls, value in worst.items())


def main() -> None:
    for name, data in POINT_MASS_SCENES.items():
        scenario = parse(data, f"{name}.toml")
        reference = simulate(scenario, "reference")
        for engine in engine_names():
            try:
                result = simulate(scenario, adapter(engine))
            except EngineUnavailable as exc:
                print(f"{name:30s} {engine:9s} skipped: {exc}")
                continue
            records = compare(reference, result, scenario.tolerance)
            verdict = "pass" if (records["verdict"] != "fail").all() else "FAIL"
            print(f"{name:30s} {engine:9s} {verdict}  {worst_by_class(records)}")
    block = POINT_MASS_SCENES["slotted-lever-point-block"]
    for scale in (1.0, 1e-3):
        g, m = block["geometry"], block["mass"]
        data = merge(block, {"geometry": {k: v * scale for k, v in g.items()},
                             "mass": {k: v * scale for k, v in m.items()}})
        scenario = parse(data, "block.toml")
        records = compare(simulate(scenario, "reference"), simulate(scenario, adapter("mujoco"), {"mode": "inverse"}),
                          scenario.tolerance).set_index("signal")
        forces = records[records["class"].isin(["force", "torque"])]["relative_error"]
        print(f"mujoco inverse, block scale {scale:g}: M43 {records.loc['M43', 'max_error']:.2g} N·m "
              f"({records.loc['M43', 'relative_error']:.2g} of the torque peak); worst force/torque {forces.max():.2g}")


if __name__ == "__main__":
    main()
