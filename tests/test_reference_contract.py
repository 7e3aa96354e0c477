"""The analytic reference passes the adapter contract every engine passes
(mechval.testing.contract): it is an adapter like the others, resolved by the
registry as "reference"."""

from __future__ import annotations

from mechval.testing.contract import AdapterContract


class TestContract(AdapterContract):
    engine = "reference"
    without_time_step = "the reference is exact at every instant: it has no time step (step_setting is empty)"
    without_model_audit = "the reference builds no engine model: it evaluates the Mechanism's own equations"
