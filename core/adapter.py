"""The adapter contract (docs/adapters.md): what every engine adapter, and
the analytic reference, implements.

An adapter turns a `Mechanism` into a model, drives it (or lets it run) as
the mechanism says, and returns raw motion and reaction columns (see
`mechval.model.mechanism`) at the requested instants, already in the Fij
convention, with a typed record of what the run did (`RunInfo`). Settings
are declared (`settings_spec`) and checked here, before any run. Mapping to
the canonical signals, health and comparison happen in the harness.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping

import numpy as np
import pandas as pd

from mechval.model.mechanism import Mechanism
from mechval.reference.planar.solver import redundant_constraints
from mechval.model.scenario import Scenario, ScenarioError
from mechval.settings import TIMESTEP, Setting

#: The finest step a setting may ask for, as steps per sample interval:
#: beyond it a run cannot finish (nor its states fit in memory).
MAX_STEPS_PER_SAMPLE = 10**6


@dataclass(frozen=True)
class RunInfo:
    """What a run did, kept apart from its settings (what it was asked to
    do): time to build the model and to simulate (s), steps taken, engine
    warnings, and engine-specific facts worth keeping (e.g. the measured
    loop-closure gap, the solver parameters actually used)."""

    build_time_s: float | None = None
    wall_time_s: float | None = None
    steps: int | None = None
    warnings: int | None = None
    facts: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, values: Mapping[str, Any]) -> "RunInfo":
        """The record of a flat mapping: its known fields, the rest as facts."""
        known = {f: values[f] for f in RUN_INFO_FIELDS if f in values}
        return cls(**known, facts={k: v for k, v in values.items() if k not in RUN_INFO_FIELDS})

    def as_dict(self) -> dict[str, Any]:
        """Flat: the fields that were recorded, then the facts."""
        fields = {f: getattr(self, f) for f in RUN_INFO_FIELDS if getattr(self, f) is not None}
        return {**fields, **self.facts}


RUN_INFO_FIELDS = ("build_time_s", "wall_time_s", "steps", "warnings")


@dataclass(frozen=True)
class PeakRates:
    """The reference motion of a run on the step rule's dense grid `t`
    (`mechval.model.kinematics.STEP_RULE_GRID` instants; a torque-driven or free
    mechanism's integrated by the forward-dynamics reference), and its Ω
    (`mechval.model.kinematics.peak_rate`): what default steps and force scales
    are made of. The harness computes it once per scene
    (`mechval.harness.plan`) and hands it to every adapter that declares
    `uses_peak_rates` (`mechval.engines.base.peak_rates` computes it)."""

    t: np.ndarray
    motion: pd.DataFrame
    rate: float


#: Where a resolved setting came from: the adapter's derived default, the
#: scenario file's [engines.NAME] table, or an explicit override.
ORIGINS = ("default", "file", "override")


@dataclass(frozen=True)
class ResolvedSettings:
    """An engine's settings for one scene, each with its origin (ORIGINS)."""

    values: Mapping[str, Any]
    origins: Mapping[str, str]


@dataclass(frozen=True)
class RawRun:
    """An adapter's output: raw columns at the requested instants, the
    reason for every column with missing values, and the run's facts."""

    frame: pd.DataFrame
    missing: Mapping[str, str] = field(default_factory=dict)
    info: RunInfo = field(default_factory=RunInfo)


class Unrepresentable(ValueError):
    """The engine cannot represent this (valid) scene, e.g. a mass below
    what its compiler accepts. `key` names the scenario key at fault;
    the harness reports it as a ScenarioError with the scenario's file."""

    def __init__(self, key: str, reason: str):
        self.key, self.reason = key, reason
        super().__init__(f"{key}: {reason}")

    def __reduce__(self):
        return type(self), (self.key, self.reason)


#: What a planar file may ask for beyond one revolute drive, gravity and
#: joint dampers (`mechanism_features`); an adapter lists in `features`
#: those it builds, and is refused the others before it runs.
FEATURES = ("several drives", "a prismatic drive", "spring-dampers", "body torques", "torque laws", "free motion",
            "redundant constraints")
#: The feature of a spatial scene (`spatial_features`), which an adapter
#: declares beside FEATURES, with the joint kinds it builds (`spatial_joints`).
SPATIAL = "spatial"


def mechanism_features(mechanism: Mechanism) -> dict[str, str]:
    """The FEATURES a mechanism uses, each with the scenario key that asks
    for it."""
    if mechanism.spatial is not None:
        return spatial_features(mechanism.spatial)
    used: dict[str, str] = {}
    if mechanism.extra_drives:
        used["several drives"] = "drive"
    for drive in mechanism.drives:
        if mechanism.joint(drive.joint).kind == "prismatic":
            used.setdefault("a prismatic drive", "drive")
    for force in mechanism.forces:
        used.setdefault("body torques" if hasattr(force, "torque") else "spring-dampers", f"force.{force.name}")
    for law in mechanism.torque_drives:
        used.setdefault("torque laws", f"torque.{law.name}")
    if mechanism.drive is None or mechanism.initial_values:     # degrees of freedom no drive prescribes
        used["free motion"] = "initial"
    if redundant_constraints(mechanism):        # a rank-deficient joint Jacobian, e.g. a parallelogram
        used["redundant constraints"] = "joint"
    return used


def spatial_features(system) -> dict[str, str]:
    """The FEATURES of a spatial scene (`mechval.reference.spatial.system.
    SpatialSystem`), each with its key; its joint kinds are checked apart
    (`EngineAdapter.spatial_joints`)."""
    used = {SPATIAL: "mechanism"}
    if len(system.drives) > 1:
        used["several drives"] = "drive"
    if any(system.joint(d.joint).kind == "prismatic" for d in system.drives):
        used["a prismatic drive"] = "drive"
    for spring in system.springs:
        used.setdefault("spring-dampers", f"force.{spring.name}")
    for load in system.loads:
        used.setdefault("body torques", f"force.{load.name}")
    for law in system.torques:
        used.setdefault("torque laws", f"torque.{law.name}")
    if system.forward_dynamics:
        used["free motion"] = "initial"
    return used


class EngineAdapter(ABC):
    name: ClassVar[str]
    #: The import name of the engine library, and its distribution on PyPI.
    library: ClassVar[str]
    distribution: ClassVar[str]
    #: What each setting accepts (type, range or choices; see `settings`).
    #: Its keys are exactly those of `default_settings`.
    settings_spec: ClassVar[Mapping[str, Setting]] = {"timestep": TIMESTEP}
    #: Settings reported by `mechval run`: name → overrides of the defaults.
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"default": {}}
    #: Work-precision sweeps (`mechval cost`): the setting that is the time
    #: step; the ladder of steps as rotations per step at the run's peak
    #: rate Ω (`step_rate`; 0.1 … 0.001 rad spans two decades of step and
    #: scales with the scene); the variants crossed with it (name →
    #: overrides; the one with no overrides is the default).
    step_setting: ClassVar[str] = "timestep"
    #: Run size (`planned_steps`, checked by the harness against --max-steps
    #: and --max-memory before any run): the settings that change the step
    #: count (a refusal names the one the file sets), and the memory model —
    #: float64 copies of the samples × signals table a run keeps, and bytes
    #: stored per engine step (measured peaks, rounded up:
    #: tests/bench/run_size_bench.py prints them).
    step_settings: ClassVar[tuple[str, ...]] = ("timestep",)
    output_copies: ClassVar[int] = 32
    bytes_per_step: ClassVar[int] = 1600
    cost_ladder: ClassVar[tuple[float, ...]] = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)
    cost_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {"default": {}}
    #: The FEATURES this adapter builds (none yet for the engines).
    features: ClassVar[frozenset[str]] = frozenset()
    #: The joint kinds of a spatial scene this adapter builds
    #: (`mechval.reference.spatial.system.JOINT_KINDS`; with "spatial" in
    #: `features`): a scene with another kind is refused before it runs.
    spatial_joints: ClassVar[frozenset[str]] = frozenset()
    #: Why the engine itself cannot run a feature the adapter leaves out
    #: (feature → reason, measured): the refusal then says so rather than
    #: that the adapter does not build it yet.
    feature_limits: ClassVar[Mapping[str, str]] = {}
    #: Whether `default_settings` takes the prepared scene's `PeakRates` as
    #: a keyword `rates` (computing them itself when it is None): the
    #: harness then computes them once per scene for every engine of a run.
    #: False (a plug-in's default): called as `default_settings(mechanism,
    #: times)`.
    uses_peak_rates: ClassVar[bool] = False

    @classmethod
    def unavailable_reason(cls) -> str:
        try:
            importlib.import_module(cls.library)
        except ImportError as exc:   # not installed, or a broken installation
            return f"{cls.library} cannot be imported ({type(exc).__name__}: {exc})"
        return ""

    @classmethod
    def version(cls) -> str:
        return importlib.metadata.version(cls.distribution)

    @abstractmethod
    def default_settings(self, mechanism: Mechanism, times: np.ndarray) -> dict[str, Any]:
        """Settings derived from the scenario so default tolerances are met."""

    @abstractmethod
    def run(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> RawRun:
        """Simulate and return raw columns at `times` (see module docstring)."""

    def check_settings(self, mechanism: Mechanism, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """(key, reason) for each resolved setting this mechanism cannot
        take, beyond what `settings_spec` checks (e.g. a pre-roll asked of a
        run that starts at its first instant); none by default. The harness
        refuses the first with the setting's origin (file or override)."""
        return []

    def defaults_for(self, scenario: Scenario, mechanism: Mechanism,
                     rates: PeakRates | None = None) -> dict[str, Any]:
        """`default_settings` of the scene (given its peak rates when this
        adapter takes them, `uses_peak_rates`). A scene whose defaults
        cannot be derived (Unrepresentable: the step rule of a torque-driven
        or free scene integrates its motion, which may leave float64's
        range) is refused as a ScenarioError naming the file and key."""
        if mechanism.spatial is not None and "spatial" not in self.features:
            return {}           # refused before it runs (`Plan.refuse_unbuilt_features`)
        try:
            if self.uses_peak_rates and rates is not None:
                return self.default_settings(mechanism, scenario.time.t, rates=rates)
            return self.default_settings(mechanism, scenario.time.t)
        except Unrepresentable as exc:
            raise ScenarioError(scenario.source, exc.key, f"{self.name}: {exc.reason}") from None

    def settings_for(self, scenario: Scenario, mechanism: Mechanism,
                     overrides: Mapping[str, Any] | None = None, rates: PeakRates | None = None,
                     defaults: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The values of `resolve_settings` (same arguments)."""
        return dict(self.resolve_settings(scenario, mechanism, overrides, rates, defaults).values)

    def resolve_settings(self, scenario: Scenario, mechanism: Mechanism,
                         overrides: Mapping[str, Any] | None = None, rates: PeakRates | None = None,
                         defaults: Mapping[str, Any] | None = None) -> ResolvedSettings:
        """Derived defaults (`defaults`, else `defaults_for` with `rates`),
        then the scenario's [engines.NAME] table, then explicit overrides,
        each value with its origin. An unknown key, a value `settings_spec`
        refuses (type, range, choices), a step that does not divide the
        sample interval, or a setting `check_settings` refuses is refused
        with the file (or "settings override") and key, before any run:
        every command resolves settings here first, so none of them lets
        such a refusal escape as a traceback."""
        settings = dict(defaults if defaults is not None else self.defaults_for(scenario, mechanism, rates))
        origins = dict.fromkeys(settings, "default")
        for origin, table in (("file", scenario.settings_for(self.name)), ("override", overrides or {})):
            source = scenario.source if origin == "file" else "settings override"
            for key, value in table.items():
                fail = lambda reason: ScenarioError(source, f"engines.{self.name}.{key}", reason)
                if key not in self.settings_spec:
                    raise fail(f"unknown setting (known: {', '.join(sorted(self.settings_spec))})")
                try:
                    value = self.settings_spec[key].parse(value)
                except ValueError as exc:
                    raise fail(str(exc)) from None
                if key == self.step_setting and len(scenario.time.t) > 1:
                    interval = float(scenario.time.t[1] - scenario.time.t[0])
                    steps = interval / value
                    if abs(steps - round(steps)) > 1e-9 * steps:
                        raise fail(f"{value!r} s does not divide the sample interval {interval:.6g} s "
                                   "(signals are read at the samples, so a whole number of steps must fit)")
                    if steps > MAX_STEPS_PER_SAMPLE:
                        raise fail(f"{value!r} s makes {steps:.3g} steps per sample interval ({interval:.6g} s), "
                                   f"more than {MAX_STEPS_PER_SAMPLE:.0e}")
                settings[key], origins[key] = value, origin
        for key, reason in self.check_settings(mechanism, settings):
            source = "settings override" if origins.get(key) == "override" else scenario.source
            raise ScenarioError(source, f"engines.{self.name}.{key}", reason)
        return ResolvedSettings(settings, origins)

    def planned_steps(self, times: np.ndarray, settings: Mapping[str, Any]) -> tuple[float, float]:
        """(steps per sample interval, steps before t = 0) a run with these
        settings takes, from the settings alone, as floats (an absurd
        setting gives inf rather than an overflow). By default: the step
        setting, shortened to divide the sample interval; no pre-roll; an
        adapter without a time step takes none."""
        if not self.step_setting:
            return 0.0, 0.0
        return steps_per_interval(times, as_float(settings[self.step_setting])), 0.0

    def audit(self, mechanism: Mechanism, times: np.ndarray, settings: Mapping[str, Any]) -> pd.DataFrame:
        """What the engine model `run` builds holds, read back and set
        against the Mechanism (`mechval.records.audit`); adapters override this."""
        raise NotImplementedError(f"{self.name}: no model audit")


def as_float(value: Any) -> float:
    """A setting as a float; a value beyond float64 counts as infinite."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def ceil_or_inf(value: float) -> float:
    return math.ceil(value) if math.isfinite(value) else math.inf


def steps_per_interval(times: np.ndarray, step: float) -> float:
    """Whole steps of at most `step` per sample interval (1 for one instant)."""
    if len(times) < 2:
        return 1.0
    return max(1.0, ceil_or_inf(float(times[1] - times[0]) / step - 1e-9))
