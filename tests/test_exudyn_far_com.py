"""Exudyn and a distant centre of mass (fourbar-seed's rocker, its centre
of mass d metres out along it).

Far beyond the mechanism's size the scene is refused up front
(`mechval.reference.limits.MAX_COM_DISTANCE`): Exudyn had called the four-bar
"redundant constraints" at d = 1e9 m, and the reference's assembly crashed
the run at 1e12 m (exit 1 with a traceback). Within the bound Exudyn's
Newton stopped ("SolveDynamic terminated") from about 30 m: its absolute
tolerance was scaled by the forces alone, while the residual's moment rows
grow with the arm; the scale now takes the arm in (`exudyn.run.force_scale`).
"""

from __future__ import annotations

import pytest

from conftest import engine_or_skip
from mechval.judging.compare import compare, passed
from mechval.testing import discrepancy_table
from mechval.harness import cli
from mechval.harness.simulate import simulate
from mechval.scenarios import builtin_path, parse
from mechval.testing.scenes import fourbar

pytestmark = pytest.mark.engine


def far_com(com: float) -> dict:
    return fourbar(mass={"rocker": {"mass": 25.0, "com": com}}, time={"end": 1.0, "samples": 101})


@pytest.mark.parametrize("setting", ["default", "index3"])
def test_a_centre_of_mass_100_m_out_runs_within_the_bounds(setting):
    """Measured worst ratios 0.063 (default, health.gap) and 0.0018 (index3, T12)."""
    adapter = engine_or_skip("exudyn")
    scenario = parse(far_com(100.0), "far-com.toml")
    records = compare(simulate(scenario, "reference"), simulate(scenario, adapter, adapter.variants[setting]),
                      scenario.tolerance_for("exudyn"), scenario=scenario.name)
    assert passed(records), discrepancy_table(records, only_failures=True)


@pytest.mark.parametrize("com", [1e9, 1e12])
@pytest.mark.parametrize("command", ["run", "simulate"])
def test_a_centre_of_mass_beyond_the_bound_is_refused_in_one_line(tmp_path, capsys, command, com):
    engine_or_skip("exudyn")
    path = tmp_path / "far-com.toml"
    text = builtin_path("fourbar-seed").read_text(encoding="utf-8")
    path.write_text(text.replace("rocker = 25.0\n", f"rocker = {{ mass = 25.0, com = {com} }}\n"), encoding="utf-8")
    out = tmp_path / "out"
    args = {"run": ["run", str(path), "--engine", "exudyn", "--out", str(out), "--quiet", "--workers", "1"],
            "simulate": ["simulate", str(path), "--engine", "exudyn", "--csv", str(out)]}[command]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}: mass.rocker: the centre of mass lies {com:.3g} m" in err
    assert not out.exists()
