"""Engine adapters: one module per engine and a small registry.

Nothing outside this package imports an engine library, and nothing here
imports one at module import time: `registry` names adapters by module path.
"""
