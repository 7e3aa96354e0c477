"""One run of one adapter on one scenario, as the harness does it for
every adapter alike (the analytic reference included): the generic
`Mechanism`, the checked settings, the adapter's raw run, then the
canonical signals and the run's health."""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from mechval.adapter import EngineAdapter, Unrepresentable
from mechval.records.engine_inputs import EngineInputs, Feed, fed_mechanism
from mechval.engines.registry import REFERENCE, adapter
from mechval.judging.health import health
from mechval.model.scenario import Scenario, ScenarioError
from mechval.records.signals import Signals, canonical_signals

from .plan import Plan, prepare


def simulate(scenario: Scenario | Plan, engine: EngineAdapter | str,
             overrides: Mapping[str, Any] | None = None, feed: Feed | None = None,
             settings: Mapping[str, Any] | None = None) -> Signals:
    """Canonical signals of `engine` (an adapter or a registered name) on
    the scenario (or its prepared `Plan`, `mechval.harness.plan`), with its
    settings, run facts and health (docs/adapters.md). A scene the engine
    cannot represent is refused as bad input, naming the scenario's file.

    The settings are `settings` when given (resolved once by the caller's
    plan, with `overrides` already applied), else resolved here.
    An engine run records what it read from the reference (`Signals.inputs`,
    `mechval.records.engine_inputs`); given a `feed` (a baseline's record), it runs
    with exactly those settings and reads instead of deriving them here."""
    engine_adapter = adapter(engine) if isinstance(engine, str) else engine
    plan = scenario if isinstance(scenario, Plan) else prepare(scenario)
    scenario, mechanism = plan.scenario, plan.mechanism
    plan.refuse_unbuilt_features(engine_adapter)
    if feed is not None:
        settings = dict(feed.settings)
    elif settings is None:
        settings = plan.for_engines([engine_adapter]).settings(engine_adapter, overrides)
    else:
        settings = dict(settings)
    # The reference's own run reads its motion at every sample: nothing to feed.
    inputs = None if engine_adapter.name == REFERENCE else EngineInputs(feed.reads if feed else None)
    try:
        raw = engine_adapter.run(mechanism if inputs is None else fed_mechanism(mechanism, inputs),
                                 scenario.time.t, settings)
    except Unrepresentable as exc:
        raise ScenarioError(scenario.source, exc.key, f"{engine_adapter.name}: {exc.reason}") from None
    signals = canonical_signals(mechanism, raw.frame, engine_adapter.name, engine_adapter.version(), settings,
                                raw.missing, health(mechanism, raw.frame, raw.missing), raw.info)
    return signals if inputs is None else dataclasses.replace(signals, inputs=inputs.record())
