"""The built-in spatial files (scenarios/spatial/*.toml) written from the
python builders of tests/spatial_mechanisms.py and
tests/spatial_benchmarks.py, so that every number in them is the
builder's own (repr: float64 exactly), derived, not rounded.

    .venv/bin/python tests/spatial_files.py        # rewrites scenarios/spatial/

tests/test_spatial_scenarios.py checks that the committed files are what
this writes, and that each file's reference agrees with its builder's.
"""

from __future__ import annotations

import sys
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mechval.model.mechanism import GROUND                                  # noqa: E402
from mechval.reference.spatial.rotation import frame_from_axis              # noqa: E402
from mechval.reference.spatial.system import SpatialSystem                  # noqa: E402
from mechval.scenarios.export import _value                                 # noqa: E402
import spatial_benchmarks as benchmarks                                      # noqa: E402
import spatial_mechanisms as mechanisms                                      # noqa: E402

FOLDER = Path(__file__).resolve().parents[1] / "scenarios" / "spatial"


@dataclass(frozen=True)
class Builtin:
    """A built-in spatial file: its builder, run and words."""

    name: str
    builder: object
    end: float
    samples: int
    description: str
    source: str
    velocities: dict = field(default_factory=dict)
    #: "extra": not in a run of all built-ins (an engine cannot meet it at
    #: its default settings; docs/engines.md says which and by how much).
    tags: tuple[str, ...] = ()
    #: [engines.NAME] tables, as TOML text with the reasons in comments.
    engines: str = ""


#: Each builder frame's own arguments to `frame_from_axis` (axis,
#: reference), by the frame's id: the file states those, so that the
#: frames it gives are the builder's bit for bit (a frame rebuilt from its
#: own columns may differ by an ulp, and near Bennett's fold an axis 6e-19
#: off moves the reference's accelerations by 1.3e-10 of their peak).
FRAME_ARGUMENTS: dict[int, tuple] = {}


def _recording(axis, reference=None, key: str = "axis"):
    frame = frame_from_axis(axis, reference, key)
    FRAME_ARGUMENTS[id(frame)] = (np.asarray(axis, dtype=float), None if reference is None
                                  else np.asarray(reference, dtype=float), frame)
    return frame


EXTRA = ("extra",)
#: PyBullet's first-order step misses the coupler joint's moment at the
#: shared step rule's step (figures measured on PyBullet 3.2.7).
RSSR_ENGINES = """
[engines.pybullet]
# The shared step rule's 5e-4 s leaves Q.Mx 1.85x its bound, 0.92x at 2.5e-4 s, 0.46x at 1.25e-4 s
# (measured on PyBullet 3.2.7: its semi-implicit Euler step is first order).
timestep = 0.000125
"""


def builtins() -> list[Builtin]:
    mechanisms.frame_from_axis = _recording      # the builders' modules look it up at call time
    four, bennett, rssr = mechanisms.SphericalFourBar(), mechanisms.Bennett(), mechanisms.RSSR()
    tumbling, top, delta = mechanisms.TumblingBody(), mechanisms.HeavyTop(), mechanisms.Delta()
    bricard, flyball = benchmarks.Bricard(), benchmarks.FlyballGovernor()
    return [
        Builtin("spherical-fourbar", four, 5.0, 801,
                "A spherical four-bar (four revolute axes through one point), its input driven over more than a turn",
                "The input–output equation of the spherical 4R chain: Chiang, Kinematics of Spherical Mechanisms, "
                "1988; McCarthy & Soh, Geometric Design of Linkages, 2nd ed. 2011, ch. 7 (closed form: "
                "mechval.reference.closed_forms.spatial.spherical_fourbar_output; builder: "
                "tests/spatial_mechanisms.py, SphericalFourBar)."),
        Builtin("bennett", bennett, 2 * np.pi, 801,
                "Bennett's overconstrained 4R linkage, driven through a full turn of its first joint (and its fold)",
                "Bennett, 'A new mechanism', Engineering 76, 1903; McCarthy & Soh 2011, ch. 9 (closed form: "
                "mechval.reference.closed_forms.spatial.bennett_angle; builder: tests/spatial_mechanisms.py, "
                "Bennett).", tags=EXTRA),
        Builtin("rssr", rssr, 4.0, 801,
                "An RSSR linkage (the coupler's idle spin held by a universal joint), its input crank accelerating",
                "The RSSR displacement equation: Suh & Radcliffe, Kinematics and Mechanisms Design, 1978 (closed "
                "form: mechval.reference.closed_forms.spatial.rssr_output; builder: tests/spatial_mechanisms.py, "
                "RSSR).", engines=RSSR_ENGINES),
        Builtin("bricard", bricard, 1.0, 101,
                "Bricard's mechanism (IFToMM benchmark A04): Grübler says 0 degrees of freedom, it has 1; "
                "released at rest under gravity, energy must hold; the benchmark's first second",
                "IFToMM / A Coruña Library of Computational Benchmark Problems, A04 (González, Dopico, Lugrís & "
                "Cuadrado, Multibody System Dynamics 16 (2006) 179–190); points and axes as its OpenSim and "
                "Exudyn implementations read them (builder: tests/spatial_benchmarks.py, Bricard)."),
        Builtin("flyball-governor", flyball, 0.005, 201,
                "The stiff flyball governor (IFToMM benchmark A05), spinning at 2π rad/s: its first 5 ms "
                "(stiff: the reference's explicit integrator is held to ~1e-4 s steps)",
                "IFToMM / A Coruña Library of Computational Benchmark Problems, A05, values as the OpenSim "
                "implementation states them (RehabEngGroup/MBSbenchmarksInOpenSim; builder: "
                "tests/spatial_benchmarks.py, FlyballGovernor).", flyball.velocities, tags=EXTRA),
        Builtin("delta-robot", delta, 1.0, 201,
                "A delta parallel robot (3-RUU: rods with a universal joint at each end), its three arms driven",
                "Tsai's condition for a translating platform (Tsai, Robot Analysis, 1999); arm angles against the "
                "closed-form inverse kinematics mechval.reference.closed_forms.spatial.delta_arm_angle (builder: "
                "tests/spatial_mechanisms.py, Delta)."),
        Builtin("t-handle", tumbling, 2.4 * tumbling.quarter, 241,
                "A free body spinning about its intermediate principal axis: the intermediate-axis "
                "(Dzhanibekov) flip, torque-free",
                "Euler's equations in Jacobi elliptic functions: Landau & Lifshitz, Mechanics, 3rd ed., §37 "
                "(closed form: mechval.reference.closed_forms.spatial.torque_free_omega; builder: "
                "tests/spatial_mechanisms.py, TumblingBody).", tumbling.velocities, tags=EXTRA),
        Builtin("heavy-top", top, 0.5 * np.pi / top.precession, 101,
                "A heavy symmetric top on a fixed point, started in steady slow precession: a quarter turn of it",
                "Goldstein, Classical Mechanics, 3rd ed., §5.7, eq. 5.76 (closed form: "
                "mechval.reference.closed_forms.spatial.top_precession_rates; builder: "
                "tests/spatial_mechanisms.py, HeavyTop).", top.velocities, tags=EXTRA),
    ]


def _vec(v) -> str:
    return _value([float(x) for x in np.ravel(v)])


def _rows(M) -> str:
    return _value([[float(x) for x in row] for row in np.asarray(M)])


def _frame_keys(frame: np.ndarray, suffix: str) -> list[str]:
    """`axis` and `reference` (with `suffix`): the builder's own arguments."""
    axis, reference, built = FRAME_ARGUMENTS[id(frame)]
    assert built is frame
    return [f"axis{suffix} = {_vec(axis)}"] + ([] if reference is None else [f"reference{suffix} = {_vec(reference)}"])


def spatial_file(b: Builtin) -> str:
    """The TOML text of a built-in spatial file."""
    system: SpatialSystem = b.builder.system
    points: dict[str, dict[str, tuple]] = {}
    for j in system.joints:
        points.setdefault(j.body_i, {})[j.name] = j.point_i
        points.setdefault(j.body_j, {})[j.name] = j.point_j
    for s in system.springs:
        points.setdefault(s.body_a, {})[f"{s.name}-a"] = s.point_a
        points.setdefault(s.body_b, {})[f"{s.name}-b"] = s.point_b
    posed = [body for body in system.bodies if np.any(body.position) or not np.array_equal(body.rotation, np.eye(3))]
    comment = lambda text: textwrap.fill(text, 110, initial_indent="# ", subsequent_indent="# ")   # noqa: E731
    out = [comment(f"Source: {b.source}"),
           comment("Written by tests/spatial_files.py from that builder: every number is the builder's own "
                   "(float64, exactly)" + ("" if posed else "; every body's frame is the world frame at the "
                                                            "assembly") + "."),
           f"name = {_value(b.name)}", 'mechanism = "spatial"', f"description = {_value(b.description)}"]
    if b.tags:
        out.append(f"tags = {_value(list(b.tags))}")
    if points.get(GROUND):
        out += ["", "[ground]"] + [f"{p} = {_vec(xyz)}" for p, xyz in points[GROUND].items()]
    for body in system.bodies:
        I = np.asarray(body.inertia)
        out += ["", "[[body]]", f"name = {_value(body.name)}", f"mass = {_value(float(body.mass))}",
                f"com = {_vec(body.com)}",
                f"inertia = {_vec([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}",
                f"points = {_value({p: [float(x) for x in xyz] for p, xyz in points.get(body.name, {}).items()})}"]
    for j in system.joints:
        out += ["", "[[joint]]", f"name = {_value(j.name)}", f"type = {_value(j.kind)}",
                f"between = {_value([f'{j.body_i}.{j.name}', f'{j.body_j}.{j.name}'])}"]
        if j.kind != "spherical":
            out += _frame_keys(j.frame_i, "")
            if j.frame_j is not j.frame_i:
                out += _frame_keys(j.frame_j, "_j")
        if j.damping:
            out.append(f"damping = {_value(float(j.damping))}")
    for d in system.drives:
        law = d.law
        out += ["", "[[drive]]", f"joint = {_value(d.joint)}", f"phi0 = {_value(float(law.phi0))}",
                f"omega0 = {_value(float(law.omega0))}", f"alpha = {_value(float(law.alpha))}"]
    for s in system.springs:
        out += ["", "[[force]]", f"name = {_value(s.name)}", 'type = "spring"',
                f"between = {_value([f'{s.body_a}.{s.name}-a', f'{s.body_b}.{s.name}-b'])}",
                f"stiffness = {_value(float(s.stiffness))}", f"free_length = {_value(float(s.free_length))}",
                f"damping = {_value(float(s.damping))}"]
    if posed:
        out += ["", "[assembly]"]
        out += [f"{body.name} = {{ position = {_vec(body.position)}, rotation = {_rows(body.rotation)} }}"
                for body in posed]
    if b.velocities:
        out += ["", "[initial]                  # velocity of each body frame's origin and angular velocity, world"]
        out += [f"{name} = {{ velocity = {_vec(v)}, omega = {_vec(om)} }}" for name, (v, om) in b.velocities.items()]
    out += ["", "[effects]", f"gravity = {_vec(system.gravity)}",
            "", "[time]", f"end = {_value(float(b.end))}", f"samples = {b.samples}"]
    if b.engines:
        out += ["", b.engines.strip()]
    return "\n".join(out) + "\n"


def main() -> None:
    FOLDER.mkdir(exist_ok=True)
    for b in builtins():
        (FOLDER / f"{b.name}.toml").write_text(spatial_file(b), encoding="utf-8")
        print(f"wrote {FOLDER / b.name}.toml")


if __name__ == "__main__":
    main()
