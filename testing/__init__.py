"""Test tools for engine adapters and for comparison runs in any repository
(`mechval.testing`, the `testing/` folder; docs/adapters.md, "Testing an
adapter", and docs/testing.md):

- `AdapterContract`: the adapter contract as one test class to subclass;
- `PlanarContract`: the planar scenes' contract (several drives, slides
  between moving links, spring-dampers, body torques, six-bars, …) as
  one more class to subclass;
- `SpatialContract`: the spatial scenes' contract (gravity and reactions
  in 3-D, a spherical joint, gyroscopic moments, a free body's momentum);
- `engine_or_skip(name)`: an adapter, or skip the test with the reason;
- `compare_with_reference(scene, engine, overrides)`: a `Comparison`
  (records, signals, reference) of one engine run against the reference;
- `assert_within_tolerance(records)`: fail with the discrepancy table;
- `discrepancy_table(records)`: that table as text;
- the pytest plugin (`mechval.testing.plugin`): marks, the
  `mechval_compare` fixture and `--mechval-report DIR`.

The names are imported on first use: pytest loads the plugin, and with it
this package, in every session of an environment that has mechval.
"""

from __future__ import annotations

import importlib

#: Public name → the module of this package that defines it.
_MODULES = {
    "AdapterContract": "contract",
    "PlanarContract": "planar_contract",
    "SpatialContract": "spatial_contract",
    "engine_or_skip": "comparison",
    "compare_with_reference": "comparison",
    "Comparison": "comparison",
    "assert_within_tolerance": "comparison",
    "discrepancy_table": "comparison",
}
__all__ = list(_MODULES)


def __getattr__(name: str):
    if name not in _MODULES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_MODULES[name]}"), name)
