"""Each scene is prepared once per run (`mechval.harness.plan`): the position
solves of one `simulate` and of one `run` are counted, `mechval list`
solves nothing, adapters take the prepared peak rates and check their
settings through a hook that knows each setting's origin, and no adapter
imports the scenario model."""

from __future__ import annotations

import pickle
import re
import traceback
from collections import Counter
from pathlib import Path

import pytest

from mechval.reference.planar import solver as planar_solver
from mechval.adapter import EngineAdapter, RawRun
from mechval.harness import cli, executors
# Imported before any test patches executors.LocalExecutor: a module first
# imported under the patch (`from .executors import LocalExecutor`) would
# keep the stand-in for every later test in this worker.
from mechval.harness import baseline_run, run, runner  # noqa: F401
from mechval.harness.executors import Done
from mechval.harness.plan import prepare
from mechval.model.kinematics import STEP_RULE_GRID, step_rate
from mechval.model.scenario import ScenarioError
from mechval.scenarios import parse

ROOT = Path(__file__).resolve().parent.parent


def asked_by(n: int) -> str:
    """Which phase asked for a solve of n instants: the step rule's grid
    (peak rates), the reference's run, an engine's run (its start), the
    report's drawing."""
    if n == STEP_RULE_GRID:
        return "peak rates"
    files = [Path(frame.filename) for frame in traceback.extract_stack()]
    for folder, phase in (("engines", "engine start"), ("reports", "drawing")):
        if any(folder in f.parts[-3:-1] for f in files):       # engines/NAME/*.py, reports/*.py
            return phase
    return "reference" if any(f.parts[-2:] == ("reference", "adapter.py") for f in files) else f"other ({n} instants)"


@pytest.fixture
def solves(monkeypatch) -> list[str]:
    """Every position solve of the general reference from here on: "check"
    for a scene's load-time check, else the phase that asked (`asked_by`)."""
    seen: list[str] = []
    solve, check = planar_solver.PlanarSolver.solve, planar_solver.PlanarSolver.check
    monkeypatch.setattr(planar_solver.PlanarSolver, "solve",
                        lambda self, t, *a, **k: seen.append(asked_by(len(t))) or solve(self, t, *a, **k))
    monkeypatch.setattr(planar_solver.PlanarSolver, "check",
                        lambda self, *a, **k: seen.append("check") or check(self, *a, **k))
    return seen


class InProcess:
    """The run's workers in this process, each task a pickled copy as a
    worker process gets it (so nothing is shared by object identity)."""

    def __init__(self, *args):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def run(self, fn, items, on_done=lambda index, done: None):
        items, results = list(items), []
        while len(results) < len(items):
            results.append(Done(fn(pickle.loads(pickle.dumps(items[len(results)])))))
            items += on_done(len(results) - 1, results[-1]) or ()
        return results


@pytest.mark.engine
def test_one_simulate_solves_the_step_rule_grid_once(solves, tmp_path):
    """jansen-leg (the general reference) × MuJoCo: the load's check, the
    plan's peak rates on the step rule's grid (for the default step and
    the limits check alike), and the engine's one read of its start."""
    pytest.importorskip("mujoco")
    assert cli.main(["simulate", "jansen-leg", "--engine", "mujoco", "--csv", str(tmp_path / "x.csv")]) == 0
    assert Counter(solves) == {"check": 1, "peak rates": 1, "engine start": 1}


@pytest.mark.engine
def test_one_run_solves_the_step_rule_grid_once(solves, tmp_path, monkeypatch):
    """`mechval run` of jansen-leg on MuJoCo (two variants, two worker
    tasks): the step rule's grid is solved once in all (by a worker), not
    once more per worker or by the parent; besides it, the load's check,
    the reference at the samples, each task's reads of its start and the
    report's drawing (made by the worker that ran the reference)."""
    pytest.importorskip("mujoco")
    monkeypatch.setattr(executors, "LocalExecutor", InProcess)
    cli.main(["run", "jansen-leg", "--engine", "mujoco", "--out", str(tmp_path / "r"), "--quiet"])
    count = Counter(solves)
    assert count.pop("engine start") in (2, 3, 4), solves     # one or two reads per task (MuJoCo's pre-roll)
    assert count == {"check": 1, "peak rates": 1, "reference": 1, "drawing": 1}, solves


def test_listing_solves_nothing(solves, capsys):
    assert cli.main(["list"]) == 0
    assert "jansen-leg" in capsys.readouterr().out and solves == []


class Stepped(EngineAdapter):
    """A plug-in that reads the prepared peak rates and refuses a setting
    the mechanism cannot take (`check_settings`)."""

    name, library, distribution = "stepped", "numpy", "numpy"
    uses_peak_rates = True
    asked: list = []

    def default_settings(self, mechanism, times, rates=None):
        self.asked.append(rates)
        return {"timestep": float(times[1] - times[0]) / 4}

    def check_settings(self, mechanism, settings):
        return [("timestep", "too coarse for this mechanism")] if settings["timestep"] > 5e-3 else []

    def run(self, mechanism, times, settings):
        raise NotImplementedError


class Plain(Stepped):
    """A plug-in of the contract before peak rates: default_settings(mechanism, times)."""

    name = "plain"
    uses_peak_rates = False

    def default_settings(self, mechanism, times):
        return {"timestep": float(times[1] - times[0]) / 4}


#: A crank-rocker at 10 rad/s sampled every 10 ms: the plug-ins' default
#: step (a quarter of that) passes their check, 10 ms does not.
SCENE = {"name": "s", "mechanism": "fourbar",
         "geometry": {"ground": 0.6, "crank": 0.25, "coupler": 0.5, "rocker": 0.5, "branch": "open"},
         "mass": {"crank": 12.5, "coupler": 25.0, "rocker": 25.0},
         "drive": {"phi0": 0.0, "omega0": 10.0, "alpha": 0.0}, "effects": {}, "time": {"end": 0.1, "samples": 11}}


def test_the_plan_hands_its_peak_rates_to_adapters_that_take_them():
    scenario = parse({**SCENE, "time": {"end": 0.001, "samples": 11}}, "s.toml")
    Stepped.asked = []
    plan = prepare(scenario, [Stepped(), Plain()])
    assert plan.rates is not None and len(plan.rates.t) == STEP_RULE_GRID
    assert plan.rates.rate == step_rate(plan.mechanism, scenario.time.t) >= 10.0    # at least the crank's ω
    assert Stepped.asked == [plan.rates]
    assert plan.settings(Plain()) == {"timestep": 1e-4 / 4}
    assert prepare(scenario, [Plain()]).rates is None       # nobody reads them: not solved


@pytest.mark.parametrize("where, source", [("file", "s.toml"), ("override", "settings override"),
                                           ("default", "s.toml")])
def test_a_refused_setting_names_where_it_came_from(where, source):
    """`check_settings` returns (key, reason); the refusal names the
    file, or "settings override", by the setting's origin."""
    coarse = {"timestep": 0.01}
    data = {**SCENE, "engines": {"stepped": coarse}} if where == "file" else SCENE
    scenario = parse(data, "s.toml", engines=None)
    overrides = coarse if where == "override" else None
    if where == "default":
        scenario = parse({**SCENE, "time": {"end": 1.0, "samples": 11}}, "s.toml")   # its default step: 25 ms
    plan = prepare(scenario, [Stepped()])
    with pytest.raises(ScenarioError, match=re.escape(f"{source}: engines.stepped.timestep: too coarse")):
        plan.settings(Stepped(), overrides)
    origins = prepare(parse(SCENE, "s.toml"), [Stepped()]).resolved(Stepped(), {"timestep": 5e-4}).origins
    assert origins == {"timestep": "override"}


def test_no_adapter_imports_the_scenario_model():
    """Adapters see the `Mechanism` and their settings, never the `Scenario`
    (its file, its [engines] table): the harness resolves settings."""
    adapters = sorted((ROOT / "engines").rglob("*.py"))
    assert len(adapters) > 10
    for path in adapters:
        assert not re.search(r"^from mechval\.model\.scenario import|^import mechval\.model\.scenario\b",
                             path.read_text(encoding="utf-8"), re.MULTILINE), path.name
