"""Exudyn's pre-roll on scenes whose loop does not close before t = 0.

A scene guarantees closure over its run only. Exudyn's pre-roll steps
along φ(t) before t = 0 (10 steps, 175 with `index3`), so that t = 0 is a
solved step and index-3's start-up transient has decayed there. Before the
fix the pre-roll's start was assembled from the file's pose (meant for
t = 0) and refused where the loop cannot close, failing valid scenes in
`mechval run` (exit 1, "the pose cannot be assembled … at t = -0.14 s").
Now it is halved until the reference closes over it on the run's branch,
and index-3's spectral radius is lowered so that the transient still dies
within the shorter pre-roll (`exudyn.run.prepare`).

The three scenes are copies of built-ins, changed here (no source):
- a slider-driven slider-crank (`slider-driven-slider-crank`, guide tilted
  along (0.96, 0.28)) that starts 8 mm inside its outer dead centre and
  moves in: the drive law extrapolated backwards pushes the slide past the
  reach of the crank and conrod (0.4 m) 85 steps before t = 0;
- `five-bar-two-drives` with its second drive moved to the pin P between
  the two moving couplers (φ = 0.64 rad rising at 1 rad/s; at 0.61 rad, a
  few dozen steps before t = 0, the loop no longer closes);
- `stephenson-six-bar` with joint O2's `between` reversed (so φ = −θ2):
  the file's pose then lies half a turn from the run's, from which the
  reference assembles at t = 0 but not at the pre-roll's start.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from conftest import engine_or_skip
from mechval.judging.compare import compare, passed
from mechval.testing import discrepancy_table
from mechval.harness import cli
from mechval.harness.simulate import simulate
from mechval.scenarios import builtin_path, load

pytestmark = pytest.mark.engine

#: name → (built-in, [(old, new) text replacements]).
SCENES = {
    "slider-near-dead-centre": ("slider-driven-slider-crank", [
        ("phi0 = 0.35", "phi0 = 0.392"),
        ("crank = 0.9\nconrod = 0.05\nslider = 0.2838", "crank = 0.3\nconrod = 0.3\nslider = 0.28")]),
    "five-bar-pin-driven": ("five-bar-two-drives", [
        ('joint = "O2"\nphi0 = 1.9\nomega0 = -1.0', 'joint = "P"\nphi0 = 0.64\nomega0 = 1.0')]),
    "stephenson-reversed-drive": ("stephenson-six-bar", [
        ('between = ["ground.O2", "crank.start"]', 'between = ["crank.start", "ground.O2"]')]),
}


def scene_file(folder, name: str):
    builtin, changes = SCENES[name]
    text = builtin_path(builtin).read_text(encoding="utf-8").replace(f'name = "{builtin}"', f'name = "{name}"')
    for old, new in changes:
        assert old in text, old
        text = text.replace(old, new)
    path = folder / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def adapter():
    return engine_or_skip("exudyn")


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scenes")
    return {name: scene_file(folder, name) for name in SCENES}


def test_mechval_run_passes_them_with_both_variants(adapter, scenes, tmp_path, capsys):
    """`mechval run --engine exudyn` runs the default and the index-3
    variant on the three scenes: exit 0, every record within its bound
    (measured worst ratios 0.013 / 0.016, 0.035 / 0.043, 0.0032 / 0.0045)."""
    status = cli.main(["run", *map(str, scenes.values()), "--engine", "exudyn", "--workers", "1", "--quiet",
                       "--out", str(tmp_path / "report")])
    assert status == 0, capsys.readouterr().out


@pytest.mark.parametrize("name", list(SCENES))
def test_mechval_simulate_writes_them(adapter, scenes, tmp_path, name):
    csv = tmp_path / "run.csv"
    assert cli.main(["simulate", str(scenes[name]), "--engine", "exudyn", "--csv", str(csv)]) == 0
    assert csv.exists()


@pytest.mark.parametrize("name, solver, requested", [
    ("slider-near-dead-centre", "index2", 10), ("slider-near-dead-centre", "index3", 175),
    ("five-bar-pin-driven", "index3", 175), ("stephenson-reversed-drive", "index3", 175)])
def test_the_pre_roll_is_shortened_only_where_the_loop_cannot_close(adapter, scenes, name, solver, requested):
    """The run info says how many steps the pre-roll took, and for index-3
    the spectral radius used: ρ = 1e-8^(1/n) when n falls short of the 175
    steps ρ = 0.9 needs. The Stephenson six-bar closes over the whole
    pre-roll once the reference assembles it from the run's own pose."""
    signals = simulate(load(scenes[name]), adapter, {"solver": solver})
    used = signals.info.facts["pre_roll_steps_used"]
    if name == "stephenson-reversed-drive" or solver == "index2":
        assert used == requested
    else:
        assert 1 <= used < requested
    if solver == "index3":
        rho = signals.info.facts["spectral_radius_used"]
        assert rho == (0.9 if used == requested else pytest.approx(1e-8 ** (1 / used), rel=1e-12))


def test_trap_a_shortened_pre_roll_at_the_set_spectral_radius_leaves_the_transient(adapter, scenes, monkeypatch):
    """Why ρ is lowered: the 43 steps the slider's loop closes over, at
    ρ = 0.9, leave index-3's start-up transient far above the default
    bounds at the first samples (measured 13× them on conrod.ax)."""
    from mechval.engines.exudyn import run as exudyn_run
    monkeypatch.setattr(exudyn_run, "index3_spectral_radius", lambda rho, steps: rho)
    scenario = load(scenes["slider-near-dead-centre"])
    records = compare(simulate(scenario, "reference"), simulate(scenario, adapter, {"solver": "index3"}),
                      scenario.tolerance_for("exudyn"), scenario=scenario.name)
    worst = records.sort_values("ratio", ascending=False).iloc[0]
    assert not passed(records) and worst["ratio"] > 5 and worst["t_max"] < 0.05, discrepancy_table(records)


def test_no_pre_roll_at_all_leaves_only_the_first_reactions_missing(adapter, scenes, monkeypatch):
    """Where not even one step before t = 0 closes, the run starts at the
    first sample: its reactions there are missing with the reason, the
    rest of the run is compared as usual."""
    from mechval.engines.exudyn import run as exudyn_run
    monkeypatch.setattr(exudyn_run, "_start_on_the_run_s_branch", lambda mechanism, t, first: pd.DataFrame())
    scenario = load(scenes["slider-near-dead-centre"])
    signals = simulate(scenario, adapter)
    assert signals.info.facts["pre_roll_steps_used"] == 0
    assert np.isnan(signals.frame["guide.Fx"].iloc[0]) and np.isfinite(signals.frame["guide.Fx"].iloc[1:]).all()
    assert "zero reactions" in signals.missing["guide.Fx"]
