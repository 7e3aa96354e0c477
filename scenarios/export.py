"""A scenario's scene written as a planar file (docs/scenario-format.md#planar-files):
the same bodies, frames, joints, drives, torque laws, initial values, force
elements and gravity, the closed form's pose at t = 0 as the assembly pose
where the scenario has a closed form, and the same time grid, tolerances and
engine tables. Loading the text gives the same scene, solved by the general
reference (`mechval export NAME`; tests/test_planar_scenarios.py checks it
against every closed form).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any, Mapping

from mechval.reference.linkages import without_closed_form
from mechval.model.mechanism import GROUND, BodyTorque, Joint, SpringDamper
from mechval.model.scenario import DEFAULT_TOLERANCE, Scenario, ScenarioError

Point = tuple[float, float]


def planar_file(scenario: Scenario) -> str:
    """The TOML text of `scenario` as a planar file named NAME-planar."""
    if scenario.mechanism == "spatial":
        raise ScenarioError(scenario.source, "mechanism", "`mechval export` writes a scene as a planar file; a "
                                                          "spatial scene has no planar form (its file is its text)")
    kind, expanded = scenario.mechanism, scenario.closed_form is not None
    scenario = without_closed_form(scenario) if expanded else scenario
    scene = scenario.scene
    points = _points(scene.joints, scene.forces)
    name = f"{scenario.name}-planar" if expanded else scenario.name
    out = [f"# The scenario {_value(scenario.name)} ({kind}) written as a planar file by `mechval export`:",
           "# the same bodies, frames, joints, drives and forces (docs/scenario-format.md#planar-files).",
           f"name = {_value(name)}", 'mechanism = "planar"',
           f"description = {_value(scenario.description + (' (as a planar file)' if expanded else ''))}"]
    if scenario.tags:
        out.append(f"tags = {_value(list(scenario.tags))}")
    out += ["", "[ground]"] + [f"{p} = {_value(xy)}" for p, xy in points.get(GROUND, {}).items()]
    for body in scene.bodies:
        out += ["", "[[body]]", f"name = {_value(body.name)}", f"mass = {_value(body.mass)}",
                f"com = {_value(body.com)}", f"izz = {_value(body.izz)}",
                f"points = {_value(points.get(body.name, {}))}"]
    for joint in scene.joints:
        out += ["", "[[joint]]", f"name = {_value(joint.name)}", f"type = {_value(joint.kind)}",
                f"between = {_value([f'{joint.body_i}.{joint.name}', f'{joint.body_j}.{joint.name}'])}"]
        if joint.kind == "prismatic":
            out.append(f"axis = {_value(joint.axis)}")
            if joint.angle is not None:
                out.append(f"angle = {_value(joint.angle)}")
        if joint.damping:
            out.append(f"damping = {_value(joint.damping)}")
    for drive in scene.drives:
        law = drive.law
        out += ["", "[[drive]]", f"joint = {_value(drive.joint)}", f"phi0 = {_value(law.phi0)}",
                f"omega0 = {_value(law.omega0)}", f"alpha = {_value(law.alpha)}"]
    for law in scene.torques:
        out += ["", "[[torque]]", f"name = {_value(law.name)}", f"joint = {_value(law.joint)}",
                f"torque = {_value(law.torque)}", f"amplitude = {_value(law.amplitude)}",
                f"frequency = {_value(law.frequency)}", f"phase = {_value(law.phase)}"]
    for value in scene.initial:
        out += ["", "[[initial]]", f"joint = {_value(value.joint)}", f"value = {_value(value.value)}",
                f"rate = {_value(value.rate)}"]
    for force in scene.forces:
        out += ["", "[[force]]", f"name = {_value(force.name)}"] + _force(force)
    out += ["", "[assembly]                  # body angles at t = 0 (rad): they pick the branch"]
    out += [f"{body} = {_value(pose.theta if pose.x is None else {'theta': pose.theta, 'x': pose.x, 'y': pose.y})}"
            for body, pose in scene.pose.items()]
    out += ["", "[effects]", f"gravity = {_value(scene.gravity)}",
            "", "[time]", f"end = {_value(scenario.time.end)}", f"samples = {scenario.time.samples}"]
    bounds = {c: b for c, b in scenario.tolerance.bounds.items() if DEFAULT_TOLERANCE.get(c) != b}
    if bounds:
        out += ["", "[tolerance]"] + [f"{c} = {_value(b)}" for c, b in bounds.items()]
    for engine, table in scenario.engines.items():
        out += ["", f"[engines.{engine}]"] + [f"{k} = {_value(v)}" for k, v in table.settings.items()]
        if table.tolerance:
            tolerance = {c: ({"bound": b, "reason": table.reasons[c]} if c in table.reasons else b)
                         for c, b in table.tolerance.items()}
            out.append(f"tolerance = {_value(tolerance)}")
    return "\n".join(out) + "\n"


def _points(joints: tuple[Joint, ...], forces) -> dict[str, dict[str, Point]]:
    """Each body's named points: a joint's point on either body is named
    after the joint, a spring's ends NAME-a and NAME-b."""
    points: dict[str, dict[str, Point]] = {}
    for joint in joints:
        points.setdefault(joint.body_i, {})[joint.name] = joint.point_i
        points.setdefault(joint.body_j, {})[joint.name] = joint.point_j
    for force in forces:
        if isinstance(force, SpringDamper):
            points.setdefault(force.body_a, {})[f"{force.name}-a"] = force.point_a
            points.setdefault(force.body_b, {})[f"{force.name}-b"] = force.point_b
    return points


def _force(force: SpringDamper | BodyTorque) -> list[str]:
    if isinstance(force, BodyTorque):
        return ['type = "torque"', f"body = {_value(force.body)}", f"torque = {_value(force.torque)}"]
    return ['type = "spring"', f"between = {_value([f'{force.body_a}.{force.name}-a', f'{force.body_b}.{force.name}-b'])}",
            f"stiffness = {_value(force.stiffness)}", f"free_length = {_value(force.free_length)}",
            f"damping = {_value(force.damping)}"]


def _value(value: Any) -> str:
    """A TOML value: numbers exact (repr), strings quoted, arrays, inline tables."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("nan" if value != value else ("inf" if value > 0 else "-inf"))
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }" if value else "{}"
    return "[" + ", ".join(_value(v) for v in value) + "]"


def _key(key: str) -> str:
    return key if BARE_KEY.fullmatch(key) else json.dumps(key, ensure_ascii=False)


BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
