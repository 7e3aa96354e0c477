"""Every spatial built-in through every engine's model audit, as `mechval
audit spatial/NAME --engine E` runs it, at the engine's default settings
(slow: the defaults solve each scene's reference on a dense grid). Each
engine's own file (tests/test_spatial_NAME.py) audits test scenes at fixed
settings in the default run."""

import pytest

from mechval.harness.audit_run import audit_scenario
from mechval.records.audit import AUDIT_RTOL, failures, format_audit
from mechval.scenarios.loader import load, spatial_builtin_names

from conftest import ENGINES


@pytest.mark.slow
@pytest.mark.engine
@pytest.mark.parametrize("name", spatial_builtin_names())
@pytest.mark.parametrize("engine", ENGINES)
def test_spatial_builtin_models_are_the_scene(engine, name):
    """No row differs or is missing, every deviation within the audit's 1e-12."""
    result = audit_scenario(load(name), engine)
    assert result.table is not None, result.error
    assert result.ok, "\n" + format_audit(failures(result.table))
    assert (result.table["deviation"].dropna() <= AUDIT_RTOL).all()
