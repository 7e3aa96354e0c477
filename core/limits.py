"""What mechval agrees to simulate: scene bounds and run-size limits.

Two kinds of refusal, both before any work and both naming the file, the key
and how much the run would take:

- `check_scene` (called by the loader): a scene float64 or the engines
  cannot simulate meaningfully (too many samples, a sample interval below
  the engines' useful range, a crank angle beyond float64's angular
  resolution, masses or inertias the engines' solvers cannot take);
- `check_run` (called by the command line with the adapter's resolved
  settings): an engine run whose step count or estimated memory exceeds the
  limits (`--max-steps`, `--max-memory`).

Every constant below is documented in README.md ("Limits"); the figures
behind the memory model come from `tests/bench/run_size_bench.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from .scenario import Scenario, ScenarioError
from .signals import signal_names

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

#: Default limits of one engine run (overridden by --max-steps, --max-memory).
#: Measured 11-34 µs per step (up to 100 on a loaded machine): 10⁷ steps
#: take 2-6 min, up to 17.
DEFAULT_MAX_STEPS = 10_000_000
DEFAULT_MAX_MEMORY = 8 * 2**30
#: Memory model per engine: (copies of the output table, bytes per step).
#: An engine run keeps `copies` float64 tables of samples × signals, plus
#: what it stores per step (MuJoCo the rollout's states, PyBullet its step
#: times, Exudyn every sensor at every step); measured peaks, rounded up.
MEMORY_MODEL = {"reference": (8, 0), "mujoco": (24, 128), "pybullet": (32, 32), "exudyn": (4, 1600)}
UNKNOWN_ENGINE_MEMORY = (32, 1600)
#: Settings that hold a pre-roll (steps before t = 0), per engine, and all
#: settings that change the step count (named as the key of a refusal).
PRE_ROLL = {"pybullet": "preroll_steps", "exudyn": "pre_roll_steps"}
STEP_SETTINGS = {"timestep", "refine", "solref_steps", "preroll_timeconsts", "spectral_radius", *PRE_ROLL.values()}


def check_scene(scenario: Scenario) -> None:
    """Refuse a scene that cannot be simulated meaningfully (see the
    constants above). Needs no arrays: runs before anything is evaluated."""
    fail = lambda key, reason: ScenarioError(scenario.source, key, reason)
    samples, end = scenario.time.samples, scenario.time.end
    if samples > MAX_SAMPLES:
        raise fail("time.samples", f"{shown_int(samples)} samples exceed the limit of {MAX_SAMPLES:,} (the "
                                   f"reference alone would need {_gib(run_size(scenario, 'reference', {}).memory)} GiB)")
    interval = end / (samples - 1)
    if not interval >= MIN_SAMPLE_INTERVAL:
        raise fail("time.end", f"the sample interval end / (samples − 1) = {interval:.3g} s is below "
                               f"{MIN_SAMPLE_INTERVAL:g} s, where the engines' steps lose their accuracy")
    law = scenario.drive
    if abs(law.phi0) > MAX_CRANK_ANGLE:
        raise fail("drive.phi0", _angle_reason(abs(law.phi0), "at t = 0"))
    angle, when = crank_angle_peak(law.phi0, law.omega0, law.alpha, end)
    if angle > MAX_CRANK_ANGLE:
        raise fail("drive", _angle_reason(angle, f"at t = {when:.6g} s") +
                   "; shorten time.end or lower omega0/alpha")
    heaviest = max(m.mass for m in scenario.mass.values())
    for link, m in scenario.mass.items():        # the moving links
        if m.mass < MIN_MASS:
            raise fail(f"mass.{link}", f"{m.mass:g} kg is below {MIN_MASS:g} kg (MuJoCo refuses masses "
                                       "≤ 1e-15 kg; PyBullet takes them for fixed bodies)")
        if heaviest / m.mass > MAX_MASS_RATIO:
            raise fail(f"mass.{link}", f"{m.mass:g} kg is {heaviest / m.mass:.3g} times lighter than the "
                                       f"heaviest link ({heaviest:g} kg); beyond {MAX_MASS_RATIO:.0e} "
                                       "the engines' solvers lose the light link")
        if 0 < m.izz < MIN_INERTIA:
            raise fail(f"mass.{link}", f"izz = {m.izz:.3g} kg·m² is below {MIN_INERTIA:g} kg·m² "
                                       "(MuJoCo refuses inertias ≤ 1e-15 kg·m² per axis)")


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


@dataclass(frozen=True)
class Limits:
    """The limits of one engine run (--max-steps, --max-memory in bytes)."""

    max_steps: float = DEFAULT_MAX_STEPS
    max_memory: float = DEFAULT_MAX_MEMORY


@dataclass(frozen=True)
class RunSize:
    """What one engine run would take. Floats, so that an absurd setting
    gives inf rather than an overflow."""

    engine: str
    steps: float        # pre-roll included
    pre_roll: float
    step: float         # s
    table_bytes: float  # the output tables (samples × signals)
    step_bytes: float   # what the engine keeps per step

    @property
    def memory(self) -> float:
        return self.table_bytes + self.step_bytes


def run_size(scenario: Scenario, engine: str, settings: Mapping[str, Any]) -> RunSize:
    """The step count and memory of `engine` with its resolved `settings`
    (`adapter.settings_for`) on the scenario, from the settings alone:
    dt = timestep / refine (MuJoCo's refine; 1 elsewhere), rounded down to
    divide the sample interval as every adapter does; plus the engine's
    pre-roll (`pre_roll_steps`)."""
    samples = scenario.time.samples
    copies, per_step = MEMORY_MODEL.get(engine, UNKNOWN_ENGINE_MEMORY)
    table = _number(samples * len(signal_names(scenario.mechanism)) * 8 * copies)
    if engine == "reference":
        return RunSize(engine, 0.0, 0.0, math.nan, table, 0.0)
    interval = scenario.time.end / (samples - 1)
    ratio = interval / (_number(settings["timestep"]) / _number(settings.get("refine", 1)))
    per_sample = max(1, _ceil(ratio - 1e-9))
    pre_roll = pre_roll_steps(engine, settings)
    steps = pre_roll + (samples - 1) * per_sample
    return RunSize(engine, steps, pre_roll, interval / per_sample, table, steps * per_step)


def pre_roll_steps(engine: str, settings: Mapping[str, Any]) -> float:
    """Steps an engine takes before t = 0 (an upper bound: MuJoCo halves its
    pre-roll where the reference cannot give a state that early)."""
    if engine == "mujoco":
        return _ceil(_number(settings["preroll_timeconsts"]) * _number(settings["solref_steps"]))
    steps = _number(settings.get(PRE_ROLL.get(engine, ""), 0))
    rho = settings.get("spectral_radius")
    if engine == "exudyn" and settings.get("solver") == "index3" and isinstance(rho, float) and 0 <= rho < 1:
        from mechval.engines.exudyn import index3_transient_steps
        steps = max(steps, index3_transient_steps(rho))
    return steps


def check_run(scenario: Scenario, engine: str, overrides: Mapping[str, Any] | None = None,
              limits: Limits = Limits()) -> RunSize:
    """Refuse an engine run over the step or memory limit, saying what it
    would take; `overrides` as for `adapter.simulate`. The key named is the
    file's step setting if it has one, else time.end (steps) or
    time.samples (memory of the output tables)."""
    if engine == "reference":
        size = run_size(scenario, engine, {})
    else:
        from mechval.engines.registry import adapter
        from .linkages import build_mechanism
        size = run_size(scenario, engine, adapter(engine).settings_for(scenario, build_mechanism(scenario), overrides))
    in_file = sorted(set(scenario.settings_for(engine)) & STEP_SETTINGS)
    step_key = f"engines.{engine}.{in_file[0]}" if in_file else "time.end"
    if size.steps > limits.max_steps:
        raise ScenarioError(scenario.source, step_key,
                            f"one {engine} run would take {size.steps:.3g} steps ({size.pre_roll:.3g} pre-roll, then "
                            f"steps of {size.step:.3g} s up to t = {scenario.time.end:g} s), more than the limit of "
                            f"{limits.max_steps:.3g} (--max-steps)")
    if size.memory > limits.max_memory:
        key = step_key if size.step_bytes > size.table_bytes else "time.samples"
        raise ScenarioError(scenario.source, key,
                            f"one {engine} run would need about {_gib(size.memory)} GiB ({scenario.time.samples:,} "
                            f"samples, {size.steps:.3g} steps), more than the limit of {_gib(limits.max_memory)} GiB "
                            "(--max-memory)")
    return size


def _number(value: Any) -> float:
    """A setting as a float; a value beyond float64 counts as infinite."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _ceil(value: float) -> float:
    return math.ceil(value) if math.isfinite(value) else math.inf


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
