"""The load-time check of a torque-driven or free scene (both formats): its
torque laws act at revolute joints, and its initial values assemble into a
consistent initial state (`mechval.reference.initial_state`: one value per degree of
freedom the drives leave, reachable, not at a toggle of the stated joints).

The run itself is integrated when the reference runs (`mechval run`,
`simulate`); a run that reaches a position its stated joints cannot
parametrise is refused then, naming the time (`mechval.reference.dynamics`).
"""

from __future__ import annotations

from typing import Mapping

from mechval.reference.dynamics import ForwardDynamics
from mechval.reference.linkages import build_mechanism
from mechval.reference.planar.constraints import MechanismError
from mechval.model.scenario import Scenario, ScenarioError


def check_initial_state(scenario: Scenario, keys: Mapping[str, str] | None = None) -> None:
    """Refuse bad torque laws and an inconsistent initial state, naming the
    file, the key and the reason. `keys` renames the first part of the
    reference's keys ("initial", "torque") to the file's own."""
    keys = keys or {}
    try:
        forward = ForwardDynamics(build_mechanism(scenario), t0=0.0)
    except MechanismError as exc:
        head = exc.key.partition(".")[0]
        raise ScenarioError(scenario.source, keys.get(head, exc.key), exc.reason) from None
    if not forward.k:
        raise ScenarioError(scenario.source, keys.get("torque", "torque"),
                            "the drives prescribe every degree of freedom: a torque law would move nothing "
                            "(leave its joint undriven and state its initial value)")
