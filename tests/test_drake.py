"""Drake adapter: the shared contract suites (testing/contract.py,
testing/planar_contract.py) run on Drake's discrete SAP plant."""

from __future__ import annotations

import pytest

from mechval.testing.contract import AdapterContract
from mechval.testing.planar_contract import PlanarContract

pytestmark = pytest.mark.engine
pytest.importorskip("pydrake")


class TestContract(AdapterContract):
    engine = "drake"
    without_model_audit = "the Drake adapter has no model audit yet"


class TestPlanarContract(PlanarContract):
    engine = "drake"
