"""Scenario dictionaries for tests, parsed with `mechval.scenarios.parse`:
a four-bar and a slider-crank, each changed by keyword (`merge`). The
contract suite builds its scenes from them; tests of an adapter may too:

    parse(fourbar(time={"end": 1.0, "samples": 101}), "short.toml")
"""

from __future__ import annotations

import copy


def fourbar(**overrides) -> dict:
    data = {
        "name": "test-fourbar", "mechanism": "fourbar",
        "geometry": {"ground": 0.6, "crank": 0.25, "coupler": 0.5, "rocker": 0.5, "branch": "open"},
        "mass": {"crank": 12.5, "coupler": 25.0, "rocker": 25.0},
        "drive": {"phi0": 0.0, "omega0": 1.0, "alpha": 1.0},
        "effects": {"gravity": [0.0, -9.81]},
        "time": {"end": 6.0, "samples": 601},
    }
    return merge(data, overrides)


def slider_crank(**overrides) -> dict:
    data = {
        "name": "test-slider", "mechanism": "slider_crank",
        "geometry": {"crank": 0.1, "conrod": 0.4, "offset": 0.0, "branch": "right"},
        "mass": {"crank": 1.0, "conrod": 2.0, "slider": 0.5},
        "drive": {"phi0": 0.0, "omega0": 10.0, "alpha": 0.0},
        "effects": {"gravity": [0.0, -9.81]},
        "time": {"end": 2.0, "samples": 401},
    }
    return merge(data, overrides)


def merge(data: dict, overrides: dict) -> dict:
    """Deep-merge overrides (a table value replaces or extends a table; None
    deletes the key)."""
    data = copy.deepcopy(data)
    for key, value in overrides.items():
        if value is None:
            data.pop(key, None)
        elif isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key] = merge(data[key], value)
        else:
            data[key] = value
    return data
