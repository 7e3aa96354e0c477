"""Each scene prepared once per run: its `Mechanism`, the reference's peak
rates over the run (the step rule's dense solve, `PeakRates`) and every
engine's derived default settings, computed here once and handed to every
phase that needs them (planning, the limits check, the engine runs, the
model audit, the cost ladder).

What is not prepared here, and why: the reference run itself (the
reference adapter's own run at the samples, once per scene,
`runner.references_for`) and each engine's start state. An engine reads its
start through the mechanism's `motion` (or `mechval.engines.base.
reference_motion`) inside its own run, at instants only it knows (its
pre-roll), so that the run's inputs are recorded and a baseline check can
feed them back (`mechval.records.engine_inputs`).

A plan lives in one process: a worker gets the resolved settings with its
task (`mechval.records.outcome.Task.settings`), builds the mechanism (no solve) and
derives nothing.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from mechval.adapter import EngineAdapter, PeakRates, ResolvedSettings, Unrepresentable, mechanism_features
from mechval.engines.base import peak_rates
from mechval.engines.registry import adapter
from mechval.reference.linkages import build_mechanism
from mechval.model.mechanism import Mechanism
from mechval.model.scenario import Scenario, ScenarioError


@dataclass(frozen=True)
class Plan:
    """One scene, prepared: `rates` is None when no engine of the plan reads
    peak rates (`EngineAdapter.uses_peak_rates`); `defaults` holds each
    engine's derived default settings (engine name → settings)."""

    scenario: Scenario
    mechanism: Mechanism
    rates: PeakRates | None
    defaults: Mapping[str, Mapping[str, Any]]

    def for_engines(self, engines: Iterable[EngineAdapter | str]) -> "Plan":
        """This plan with the defaults of `engines` too: the peak rates
        solved once, if one of them reads them and they are not here yet;
        each engine's defaults derived once (a scene whose defaults cannot
        be derived is a ScenarioError naming the file and key)."""
        adapters = [adapter(e) if isinstance(e, str) else e for e in engines]
        rates = self.rates
        readers = [a for a in adapters if a.uses_peak_rates]
        if rates is None and readers:
            try:
                rates = peak_rates(self.mechanism, self.scenario.time.t)
            except Unrepresentable as exc:      # as the first engine's own default step would be refused
                raise ScenarioError(self.scenario.source, exc.key, f"{readers[0].name}: {exc.reason}") from None
        defaults = dict(self.defaults)
        for engine_adapter in adapters:
            if engine_adapter.name not in defaults:
                defaults[engine_adapter.name] = engine_adapter.defaults_for(self.scenario, self.mechanism, rates)
        return dataclasses.replace(self, rates=rates, defaults=defaults)

    def resolved(self, engine: EngineAdapter | str, overrides: Mapping[str, Any] | None = None) -> ResolvedSettings:
        """The engine's settings with their origins: the prepared defaults,
        the file's [engines.NAME] table, then `overrides`, checked
        (`EngineAdapter.resolve_settings`)."""
        engine_adapter = adapter(engine) if isinstance(engine, str) else engine
        return engine_adapter.resolve_settings(self.scenario, self.mechanism, overrides, self.rates,
                                               self.defaults[engine_adapter.name])

    def settings(self, engine: EngineAdapter | str, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The values of `resolved`."""
        return dict(self.resolved(engine, overrides).values)

    @property
    def features(self) -> dict[str, str]:
        """`mechanism_features`, found once per plan (a rank test of the
        joints' Jacobian; asked for every engine). Not a functools.
        cached_property: on Python 3.11 that holds one lock for every plan
        while it computes, and `mechval run` builds plans while its pool
        forks workers; a worker forked in that moment inherits the lock
        held by a thread it does not have, and hangs at its first plan
        (seen: `mechval run` stalled, a worker asleep in that lock)."""
        if "_features" not in self.__dict__:
            object.__setattr__(self, "_features", mechanism_features(self.mechanism))
        return self.__dict__["_features"]

    def refusal(self, engine_adapter: EngineAdapter | str) -> str:
        """Why the adapter declares it cannot build this scene (key and
        reason of `refuse_unbuilt_features`), or ""."""
        try:
            self.refuse_unbuilt_features(adapter(engine_adapter) if isinstance(engine_adapter, str) else engine_adapter)
        except ScenarioError as exc:
            return f"{exc.key}: {exc.reason}"
        return ""

    def refuse_unbuilt_features(self, engine_adapter: EngineAdapter) -> None:
        """A ScenarioError naming the file and key of the first feature of
        the scene the adapter does not build (`mechanism_features`)."""
        for feature, key in self.features.items():
            if feature not in engine_adapter.features:
                why = engine_adapter.feature_limits.get(feature)
                raise ScenarioError(self.scenario.source, key, f"{engine_adapter.name}: " + (
                    f"cannot run {feature}: {why}" if why else f"its adapter does not build {feature} yet"))
        for joint in self.mechanism.spatial.joints if self.mechanism.spatial is not None else ():
            if joint.kind not in engine_adapter.spatial_joints:
                raise ScenarioError(self.scenario.source, self.scenario.key(f"joint.{joint.name}.kind"),
                                    f"{engine_adapter.name}: its adapter does not build {joint.kind} joints "
                                    f"(it builds: {', '.join(sorted(engine_adapter.spatial_joints)) or 'none'})")


def prepare(scenario: Scenario, engines: Iterable[EngineAdapter | str] = ()) -> Plan:
    """The scene's plan for these engines: the mechanism built once (which
    solves nothing), then `Plan.for_engines`."""
    return Plan(scenario, build_mechanism(scenario), None, {}).for_engines(engines)


def planned(scene: Scenario | Plan, engines: Iterable[EngineAdapter | str] = ()) -> Plan:
    """The plan of a scenario, or the given plan, for these engines too."""
    return (scene if isinstance(scene, Plan) else prepare(scene)).for_engines(engines)


def scenario_of(scene: Scenario | Plan) -> Scenario:
    return scene.scenario if isinstance(scene, Plan) else scene
