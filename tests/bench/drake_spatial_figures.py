"""Drake on the spatial scenes of tests/test_spatial_drake.py: per scene
the integrator and step of the defaults, the worst error over its bound
(mechval's default tolerances, the columns the reference reports) and
the CPU time of the run and its reference; the RK3 scenes with SAP forced
on them too; then A04's own measure, Bricard's mechanical energy over
10 s, at refine 1, 4, 16. The figures of docs/engines.md, "Drake: spatial
scenes". Prints; asserts nothing (about 1.5 min of CPU).

    .venv/bin/python tests/bench/drake_spatial_figures.py
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mechval.model.scenario import DEFAULT_TOLERANCE  # noqa: E402
from spatial_benchmarks import Bricard, FlyballGovernor  # noqa: E402
from spatial_mechanisms import RSSR, Bennett, Delta, HeavyTop, SphericalFourBar, TumblingBody, unit  # noqa: E402
from test_spatial_drake import errors, loaded_rssr, spring_pendulum, with_velocities  # noqa: E402
from test_spatial_joint_kinds import sliding_body  # noqa: E402

SAP = {"integrator": "sap"}


def sliding(kind: str):
    system, axis = sliding_body(kind, (0.3, -0.2, 1.0))
    velocity = 0.4 * axis if kind == "cylindrical" else 0.5 * unit(np.cross(axis, [1.0, 0.0, 0.0]))
    return dataclasses.replace(system, velocities={"body": (tuple(velocity), tuple(6.0 * axis))})


def scenes():
    second, flyball = np.linspace(0.0, 1.0, 21), FlyballGovernor()
    yield "RSSR", RSSR().system, second, {}
    yield "spherical four-bar", SphericalFourBar().system, second, {}
    yield "Bennett", Bennett().system, second, {}
    yield "delta", Delta().system, second, {}
    yield "RSSR spring+load", loaded_rssr(torque=False), second, {}
    yield "T-handle 4 s", with_velocities(TumblingBody()), np.linspace(0.0, 4.0, 81), {}
    yield "T-handle 4 s SAP", with_velocities(TumblingBody()), np.linspace(0.0, 4.0, 81), SAP
    yield "heavy top 0.25 s", with_velocities(HeavyTop()), np.linspace(0.0, 0.25, 26), {}
    yield "heavy top 0.25 s SAP", with_velocities(HeavyTop()), np.linspace(0.0, 0.25, 26), SAP
    yield "Bricard 2 s", Bricard().system, np.linspace(0.0, 2.0, 41), {}
    yield "Bricard 2 s refine 32", Bricard().system, np.linspace(0.0, 2.0, 41), {"refine": 32}
    yield "A05 5 ms", dataclasses.replace(flyball.system, velocities=flyball.velocities), \
        np.linspace(0.0, 0.005, 11), {}
    yield "spring chain", spring_pendulum(), np.linspace(0.0, 1.0, 51), {}
    yield "spring chain SAP", spring_pendulum(), np.linspace(0.0, 1.0, 51), SAP
    for kind in ("cylindrical", "planar"):
        yield kind, sliding(kind), np.linspace(0.0, 0.5, 26), {}
        yield f"{kind} SAP", sliding(kind), np.linspace(0.0, 0.5, 26), SAP


def bricard_energy() -> None:
    """A04's measure: the largest change of the mechanical energy over 10 s."""
    from mechval.engines.drake.spatial import run_spatial, spatial_defaults, spatial_rate
    from mechval.reference.spatial.columns import body_state
    from mechval.reference.spatial.dynamics import energy
    system, t = Bricard().system, np.linspace(0.0, 10.0, 1001)
    defaults = spatial_defaults(system, t, spatial_rate(system, t, dense=2001))
    for refine in (1, 4, 16):
        clock = time.process_time()
        pose, w, _ = body_state(system, run_spatial(system, t, {**defaults, "refine": refine}).frame)
        E = energy(system, pose, w)
        print(f"Bricard 10 s refine {refine:<2}: energy change at most {np.abs(E - E[0]).max():.3g} J "
              f"(E0 {E[0]:.4g} J), {time.process_time() - clock:.1f} s CPU", flush=True)


def main() -> None:
    for name, system, t, overrides in scenes():
        clock = time.process_time()
        found, chosen = errors(system, t, **overrides)
        cpu = time.process_time() - clock
        ratios = {c: e / DEFAULT_TOLERANCE[c] for c, e in found.items()}
        worst = max(ratios, key=ratios.get)
        print(f"{name:<24} {chosen['integrator']} dt {chosen['timestep']:.3g} refine {chosen['refine']}: "
              f"worst {ratios[worst]:.3g} × bound ({worst}), {cpu:.1f} s CPU", flush=True)
    bricard_energy()


if __name__ == "__main__":
    main()
