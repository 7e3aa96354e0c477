"""What mechval agrees to simulate: the bounds of a scene.

`check_scene` (called by the loader) refuses, before any work and naming the
file, the key and the reason, a scene float64 or the engines cannot simulate
meaningfully: too many samples, a sample interval below the engines' useful
range, a crank angle beyond float64's angular resolution, masses or inertias
the engines' solvers cannot take. The size of one engine run (steps,
memory) is the harness's check (`mechval.harness.run_limits`).

Every constant below is documented in README.md ("Limits").
"""

from __future__ import annotations

import math

from mechval.model.scenario import Scenario, ScenarioError
from mechval.adapter import as_float
from mechval.reference.adapter import ReferenceAdapter
from mechval.model.drive import DriveLaw
from mechval.model.scene import signal_map as scene_signal_map
from mechval.reference.spatial.mechanism import spatial_signal_map

#: Most output instants per scenario. The loader itself evaluates the
#: reference at every sample (closure and trust checks): at 10⁶ samples that
#: takes ~12 s and ~0.7 GB, and the CSV ~0.4 GB; 10⁷ took 7 min and 6.8 GB.
MAX_SAMPLES = 1_000_000
#: Shortest sample interval (s). The engines' step is at most the interval:
#: PyBullet's drive torque on fourbar-seed is 3e-5 off at a 1 µs interval,
#: 4e-3 at 0.1 µs and 10⁴× at 0.1 ns; at 5e-324 s the interval rounds to 0.
MIN_SAMPLE_INTERVAL = 1e-6
#: Largest crank angle |φ(t)| over the run (rad). Engines advance and read
#: back absolute angles; float64 resolves 1e6 rad to 1.2e-10 rad, so even
#: 10⁷ steps (the default step limit) of rounding stay below 6e-4 rad, under
#: the default angle tolerance of 1e-3 rad. At 1e15 rad one ulp is 0.125 rad.
MAX_CRANK_ANGLE = 1e6
#: Largest ratio of the heaviest to the lightest moving mass. PyBullet's
#: drive torque drifts 6e-5 at 2.5e10, 3 % at 2.5e12 and at 2.5e14 the light
#: link acts as fixed (torque 0); 1e9 keeps a factor 25 from the first.
MAX_MASS_RATIO = 1e9
#: Smallest mass (kg) and rotational inertia izz (kg·m², the uniform-bar
#: m·L²/12 when not given; 0 allowed where the file allows a point mass) of
#: a moving link. MuJoCo refuses masses and inertias per axis at or below
#: its mjMINVAL = 1e-15 (izz is split over two axes: izz ≥ 2e-15).
MIN_MASS = 1e-9
MIN_INERTIA = 1e-14
#: Farthest centre of mass from its link's nearest joint, in units of the
#: mechanism's size (its scene's largest joint coordinate). Beyond it
#: the centre of mass sets the scale of the solvers' coordinates and the
#: joints drown in their rounding. fourbar-seed (size 0.6 m) with the
#: rocker's centre of mass 1e5 m out (1.7e5 sizes) fails every engine
#: (PyBullet 70×, MuJoCo 2e3× its bounds, Exudyn's solver stops) and the
#: general reference can no longer assemble its planar twin; 5e3 m out it
#: follows the twin as with the centre of mass on the rocker (angles within
#: 3e-12 rad; tests/test_limits.py); from 1e8 m its rank test calls the
#: four-bar redundant. Engines lose accuracy earlier (MuJoCo's default step
#: from ~100 m out, Exudyn's closure from ~1e3 m; PyBullet holds to 7e4 m):
#: out of tolerance, not refused.
MAX_COM_DISTANCE = 1e4


def check_scene(scenario: Scenario) -> None:
    """Refuse a scene that cannot be simulated meaningfully (see the
    constants above). Needs no arrays: runs before anything is evaluated."""
    fail = lambda key, reason: ScenarioError(scenario.source, key, reason)
    samples, end = scenario.time.samples, scenario.time.end
    if samples > MAX_SAMPLES:
        raise fail("time.samples", f"{shown_int(samples)} samples exceed the limit of {MAX_SAMPLES:,} (the "
                                   f"reference alone would need {_gib(reference_bytes(scenario))} GiB)")
    interval = end / (samples - 1)
    if not interval >= MIN_SAMPLE_INTERVAL:
        raise fail("time.end", f"the sample interval end / (samples − 1) = {interval:.3g} s is below "
                               f"{MIN_SAMPLE_INTERVAL:g} s, where the engines' steps lose their accuracy")
    for key, law in _drive_laws(scenario):
        if abs(law.phi0) > MAX_CRANK_ANGLE:
            raise fail(f"{key}.phi0", _angle_reason(abs(law.phi0), "at t = 0"))
        angle, when = crank_angle_peak(law.phi0, law.omega0, law.alpha, end)
        if angle > MAX_CRANK_ANGLE:
            raise fail(key, _angle_reason(angle, f"at t = {when:.6g} s") + "; shorten time.end or lower omega0/alpha")
    for value in scenario.scene.initial:        # a torque-driven or free run's start
        if abs(value.value) > MAX_CRANK_ANGLE:
            raise fail(scenario.key(f"initial.{value.joint}"), _angle_reason(abs(value.value), "at t = 0"))
    masses = _masses(scenario)
    heaviest = max(mass for _, mass, _ in masses)
    for key, mass, izz in masses:        # the moving links
        if mass < MIN_MASS:
            raise fail(key, f"{mass:g} kg is below {MIN_MASS:g} kg (MuJoCo refuses masses "
                            "≤ 1e-15 kg; PyBullet takes them for fixed bodies)")
        if heaviest / mass > MAX_MASS_RATIO:
            raise fail(key, f"{mass:g} kg is {heaviest / mass:.3g} times lighter than the "
                            f"heaviest link ({heaviest:g} kg); beyond {MAX_MASS_RATIO:.0e} "
                            "the engines' solvers lose the light link")
        if 0 < izz < MIN_INERTIA:
            raise fail(key, f"izz = {izz:.3g} kg·m² is below {MIN_INERTIA:g} kg·m² "
                            "(MuJoCo refuses inertias ≤ 1e-15 kg·m² per axis)")
    size = _size(scenario)
    for key, distance in _com_distances(scenario):
        if not distance <= MAX_COM_DISTANCE * size:
            raise fail(key, f"the centre of mass lies {distance:.3g} m from its link's nearest joint, more than "
                            f"{MAX_COM_DISTANCE:.0e} times the mechanism's size ({size:.3g} m): the joints would "
                            "drown in the rounding of its coordinates")


def _drive_laws(scenario: Scenario) -> list[tuple[str, DriveLaw]]:
    """(key, law) of every drive."""
    return [(scenario.key(f"drive[{k}]"), drive.law) for k, drive in enumerate(scenario.scene.drives)]


def _masses(scenario: Scenario) -> list[tuple[str, float, float]]:
    """(key, mass, izz) of every moving body."""
    return [(scenario.key(f"body[{k}]"), b.mass, b.izz) for k, b in enumerate(scenario.scene.bodies)]


def _size(scenario: Scenario) -> float:
    """The mechanism's size (m): its largest joint coordinate (body
    frames; world for the ground)."""
    values = [abs(v) for j in scenario.scene.joints for p in (j.point_i, j.point_j) for v in p]
    return max(values, default=0.0) or 1.0


def _com_distances(scenario: Scenario) -> list[tuple[str, float]]:
    """(key, distance in m) of every moving body's centre of mass from the
    nearest of its joint points."""
    distances = []
    for k, body in enumerate(scenario.scene.bodies):
        points = [p for j in scenario.scene.joints for b, p in ((j.body_i, j.point_i), (j.body_j, j.point_j))
                  if b == body.name]
        distances.append((scenario.key(f"body[{k}].com"), min((math.dist(body.com, p) for p in points),
                                                              default=0.0)))
    return distances


def crank_angle_peak(phi0: float, omega0: float, alpha: float, end: float) -> tuple[float, float]:
    """max |φ(t)| over [0, end] for φ = phi0 + omega0·t + ½·alpha·t², and
    where: at an end of the run or at the turning point t = −omega0/alpha."""
    candidates = [0.0, end]
    if alpha != 0 and 0 < -omega0 / alpha < end:
        candidates.append(-omega0 / alpha)
    return max((abs(phi0 + omega0 * t + 0.5 * alpha * t * t), t) for t in candidates)


def _angle_reason(angle: float, when: str) -> str:
    ulp = math.ulp(angle) if math.isfinite(angle) else math.inf
    return (f"the crank angle reaches {angle:.3g} rad {when}, beyond {MAX_CRANK_ANGLE:.0e} rad: "
            f"float64 resolves it only to {ulp:.2g} rad")


def reference_bytes(scenario: Scenario) -> float:
    """The reference's output tables at the scenario's samples (bytes)."""
    return as_float(scenario.time.samples) * signal_count(scenario) * 8 * ReferenceAdapter.output_copies


def signal_count(scenario: Scenario) -> int:
    """Columns of the scenario's canonical signals (t included)."""
    closed = scenario.closed_form
    if scenario.mechanism == "spatial":
        return 1 + len(spatial_signal_map(scenario.scene))
    return 1 + len(closed.signal_map if closed else scene_signal_map(scenario.scene))


def _gib(size: float) -> str:
    return f"{size / 2**30:.3g}" if size < 2**30 * 1e6 else "over a million"


def shown_int(value: int) -> str:
    """An integer for a message: in full when short, else its size."""
    if abs(value) < 10**15:
        return f"{value:,}"
    if abs(value) < 10**300:
        return f"{float(value):.3g}"
    try:
        digits = len(str(abs(value)))
    except ValueError:                      # beyond Python's 4300-digit conversion limit
        digits = int(abs(value).bit_length() * math.log10(2)) + 1
    return f"{'-' if value < 0 else ''}~1e{digits - 1}"
