"""What the benchmark scripts share: their command line and best-of timing."""

from __future__ import annotations

import argparse
import time
from typing import Callable

from mechval.scenarios import builtin_names, load


def timed(fn: Callable[[], object]) -> Callable[[], float]:
    """A callable that runs fn and returns its wall time (s)."""
    def run() -> float:
        start = time.perf_counter()
        fn()
        return time.perf_counter() - start
    return run


def interleaved_times(repeats: int, *runs: Callable[[], float]) -> list[list[float]]:
    """`repeats` times of each run (each returns the time it measured), the
    runs interleaved in every round so that all see the same load."""
    times: list[list[float]] = [[] for _ in runs]
    for _ in range(repeats):
        for k, run in enumerate(runs):
            times[k].append(run())
    return times


def best_times(repeats: int, *runs: Callable[[], float]) -> list[float]:
    """Best of `repeats` interleaved rounds for each run."""
    return [min(times) for times in interleaved_times(repeats, *runs)]


def scenario_arguments(doc: str, repeats: int = 3) -> argparse.Namespace:
    """SCENARIO... (default: the built-ins not tagged hard) and --repeats."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=[n for n in builtin_names() if "hard" not in load(n).tags])
    parser.add_argument("--repeats", type=int, default=repeats)
    return parser.parse_args()
