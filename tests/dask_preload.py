"""A Dask worker preload (`dask worker ADDRESS --preload tests/dask_preload.py`,
or LocalCluster(preload=[...])): registers the stand-in engines of
tests/fake_engines.py in the worker, as the tests register them in their
own process, so that tasks naming them run there."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fake_engines import registered  # noqa: E402
from mechval.engines import registry  # noqa: E402

registry.targets = registered()
