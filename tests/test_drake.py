"""Drake adapter: the shared contract suites (testing/contract.py,
testing/planar_contract.py) run on Drake's discrete SAP plant, with each
case Drake's first-order step cannot meet at the default settings kept as
a strict xfail with its measured figure (docs/engines.md, Drake)."""

from __future__ import annotations

import pytest

from mechval.testing.contract import DYNAMIC, AdapterContract
from mechval.testing.planar_contract import PlanarContract
from mechval.testing.planar_scenes import SCENES

pytestmark = pytest.mark.engine
pytest.importorskip("pydrake")

#: Measured on Drake 1.51.1 (timestep 6.06e-4 s by the step rule): the
#: falling four-bar's coupler.y is 19.9 × its bound at the default step,
#: 4.9 × at refine 4, 2.0 × at refine 10 — first order in the step.
FREE_FOURBAR = ("Drake's step is first order: the falling four-bar is 20x the position bound at the default step "
                "(4.9x at refine 4, 2.0x at refine 10)")
#: Planar scenes out of the default tolerances at the default settings,
#: measured on Drake 1.51.1 (worst signal, its error over its bound); not
#: yet explained, so kept as strict xfails rather than bounds.
PLANAR_OUT = {
    "slider-driven": "B.Fx 51x its bound, conrod.ax 5.4x (a prismatic drive: the cut pin's force, from the "
                     "momentum balance, is off)",
    "slider-driven-offset-com": "B.Fx 51x its bound, conrod.ax 5.4x (as slider-driven)",
    "pin-driven-five-bar": "L4.alpha 2.4x its bound, every force ~2.4x (a first-order step on a fast two-drive scene)",
    "ground-second": "conrod.vy 1.0002x its bound (0.005001 against 0.005)",
}


class TestContract(AdapterContract):
    engine = "drake"

    @pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=FREE_FOURBAR))
                                      if n == "free-fourbar" else n for n in DYNAMIC])
    def test_follows_the_forward_dynamics_reference(self, adapter, name):
        super().test_follows_the_forward_dynamics_reference(adapter, name)


class TestPlanarContract(PlanarContract):
    engine = "drake"

    @pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=PLANAR_OUT[n]))
                                      if n in PLANAR_OUT else n for n in SCENES])
    def test_meets_the_default_tolerances(self, adapter, name):
        super().test_meets_the_default_tolerances(adapter, name)
