"""Shared fixtures: scenarios, the cached reference, engine adapters."""

from __future__ import annotations

import functools

import pytest

from mechval.engines.registry import ENGINE_NAMES, EngineUnavailable, adapter
from mechval.reference import simulate_reference
from mechval.scenarios import builtin_names, load

BUILTIN = builtin_names()


@functools.lru_cache(maxsize=None)
def builtin_scenario(name: str):
    return load(name)


@functools.lru_cache(maxsize=None)
def builtin_reference(name: str):
    return simulate_reference(builtin_scenario(name))


def engine_or_skip(name: str):
    """The named adapter, or skip the test with the reason it is unavailable."""
    try:
        return adapter(name)
    except EngineUnavailable as exc:
        pytest.skip(str(exc))


@pytest.fixture(params=ENGINE_NAMES)
def engine(request):
    return engine_or_skip(request.param)
