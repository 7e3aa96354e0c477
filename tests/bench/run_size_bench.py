"""Measure the memory model each adapter declares (`output_copies`, `bytes_per_step`) and the time
per step behind DEFAULT_MAX_STEPS: per engine, the peak resident memory of
one run in a fresh process at three sizes of fourbar-seed (constant
10 rad/s): few samples and steps, ten times the steps, many samples.

    .venv/bin/python tests/bench/run_size_bench.py [--engine NAME ...]

Prints bytes per step, copies of the output table (samples × signals ×
8 B) and seconds per step, next to the values the adapters declare.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

#: Samples of the "many samples" run.
DENSE = 300_001

CHILD = r"""
import json, resource, sys, time, tomllib
from mechval.scenarios import builtin_path, parse
from mechval.harness.simulate import simulate
engine, end, samples = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
data = tomllib.loads(builtin_path("fourbar-seed").read_text(encoding="utf-8"))
data.update(time={"end": end, "samples": samples}, drive={"phi0": 0.0, "omega0": 10.0, "alpha": 0.0})
scene = parse(data, "fourbar-seed-sized.toml")
from mechval.engines.registry import adapter
engine_adapter = adapter(engine)
run = lambda: simulate(scene, engine_adapter)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
signals = run()
wall = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"peak": peak * 1024, "before": before * 1024, "wall": wall, "columns": signals.frame.shape[1],
                  "steps": signals.info.steps or 0}))
"""


def measure(engine: str, end: float, samples: int) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, engine, str(end), str(samples)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    from mechval.engines.registry import adapter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--engine", action="append", help="engine (repeatable; default: reference and all three)")
    engines = parser.parse_args().engine or ["reference", "mujoco", "pybullet", "exudyn"]
    print(f"{'engine':<10} {'B/step':>8} {'model':>6} {'copies':>7} {'model':>6} {'µs/step':>8}")
    for engine in engines:
        base, long, dense = measure(engine, 10.0, 601), measure(engine, 100.0, 601), measure(engine, 10.0, DENSE)
        extra_steps = long["steps"] - base["steps"]
        per_step = (long["peak"] - base["peak"]) / extra_steps if extra_steps else 0.0
        table = (dense["peak"] - base["peak"] - per_step * (dense["steps"] - base["steps"]))
        copies = table / ((DENSE - 601) * dense["columns"] * 8)
        us_per_step = 1e6 * long["wall"] / long["steps"] if long["steps"] else float("nan")
        model_copies, model_step = adapter(engine).output_copies, adapter(engine).bytes_per_step
        print(f"{engine:<10} {per_step:8.0f} {model_step:6d} {copies:7.1f} {model_copies:6d} {us_per_step:8.1f}")


if __name__ == "__main__":
    main()
