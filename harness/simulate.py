"""One run of one adapter on one scenario, as the harness does it for
every adapter alike (the analytic reference included): the generic
`Mechanism`, the checked settings, the adapter's raw run, then the
canonical signals and the run's health."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any, Mapping

from mechval.adapter import EngineAdapter, Unrepresentable
from mechval.records.engine_inputs import EngineInputs, Feed, fed_mechanism
from mechval.engines.registry import REFERENCE, EngineUnavailable, UnknownEngine, adapter
from mechval.judging.health import health
from mechval.model.scenario import Scenario, ScenarioError, one_line
from mechval.records.signals import Signals, canonical_signals

from .defaults import Limits
from .plan import Plan, prepare
from .preflight import EngineFailure, check_csv, check_runs, load_scenario


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


def simulate_command(scenario_name: str, engine: str, csv: Path, limits: Limits = Limits()) -> int:
    """`mechval simulate`: one engine's canonical signals written to `csv`,
    or nothing written and one line saying why."""
    scenario = load_scenario(scenario_name)
    check_csv(csv)
    plan = prepare(scenario, [engine])
    settings = plan.settings(engine)
    check_runs([(scenario, engine, settings)], limits)
    try:
        signals = simulate(plan, engine, settings=settings)
    except (ScenarioError, EngineUnavailable, UnknownEngine, KeyboardInterrupt):
        raise
    except Exception as exc:    # the engine's own failure (a solver that gives up): one line, exit 1
        raise EngineFailure(f"{engine} on {scenario.source or scenario.name}: {type(exc).__name__}: "
                            f"{one_line(str(exc))}; nothing written to {csv}") from None
    unexplained = signals.unexplained_gaps()
    if unexplained:
        # An engine that blew up must not leave a CSV that looks like data.
        raise EngineFailure(f"{engine} returned non-finite values without a reason "
                            f"({'; '.join(unexplained)}); nothing written to {csv}")
    signals.to_csv(csv)
    for name, reason in signals.missing.items():
        print(f"note: {name}: missing values ({reason})", file=sys.stderr)
    print(f"wrote {csv}: {len(signals.frame)} samples × {signals.frame.shape[1]} columns "
          f"({engine} {signals.version})")
    return 0
