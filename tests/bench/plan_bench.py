"""Each scene prepared once (issue 24 §2): what `mechval list` (and which
heavy modules it imports: none), one
`simulate` and one `run` cost, where a simulate's time goes, and how many
position solves each makes, for this checkout or another one (before and
after a change):

    .venv/bin/python tests/bench/plan_bench.py [--tree DIR] [--repeats N] [--skip-run]

--tree DIR measures the mechval of another checkout of this repository
(e.g. `git worktree add /tmp/before COMMIT`) with this checkout's
installed environment: every measurement runs in a fresh process whose
`mechval` package is DIR's. Wall time is the best of N; CPU time is the
process's and its workers'. The machine may be shared: the load average is
printed, and CPU time is the steadier figure.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent.parent
SIMULATE = ["simulate", "jansen-leg", "--engine", "mujoco"]
RUN = ["run", "jansen-leg", "fourbar-seed", "fourbar-falling", "--workers", "2", "--quiet"]

#: Run first in every measured process: point the installed editable
#: `mechval` at the checkout measured (setuptools' editable finder maps
#: each package to a folder of this checkout).
PRELUDE = """
import sys, importlib
finder = next(m for name, m in list(sys.modules.items()) if name.startswith("__editable___mechval"))
for package, folder in list(finder.MAPPING.items()):
    finder.MAPPING[package] = folder.replace({here!r}, {tree!r})
"""

#: Counts the general reference's position solves (the load's check, and
#: each solve by its number of instants) of one command run in-process,
#: its engine workers too (in this process, each task a pickled copy).
COUNT = """
import pickle, json
from mechval.reference.planar import solver as planar_solver
from mechval.harness import cli, runner
from mechval.harness.executors import Done
seen = []
solve, check = planar_solver.PlanarSolver.solve, planar_solver.PlanarSolver.check
planar_solver.PlanarSolver.solve = lambda self, t, *a, **k: seen.append(len(t)) or solve(self, t, *a, **k)
planar_solver.PlanarSolver.check = lambda self, *a, **k: seen.append("check") or check(self, *a, **k)
class InProcess:
    def __init__(self, *args): pass
    def run(self, fn, items, on_done=lambda index, done: None):
        out = []
        for index, item in enumerate(items):
            out.append(Done(fn(pickle.loads(pickle.dumps(item))))); on_done(index, out[-1])
        return out
runner.LocalExecutor = InProcess
cli.main({argv!r})
print("SOLVES " + json.dumps(seen))
"""

#: Profiles one command in-process and prints the cumulative time of the
#: functions that make up a simulate.
PROFILE = """
import cProfile, pstats, json
from mechval.harness import cli
import mechval.engines.mujoco.adapter, mujoco          # imports are not the command's work
profile = cProfile.Profile()
profile.runcall(cli.main, {argv!r})
stats = pstats.Stats(profile).stats
parts = {{"load and check the scene": ("loader.py", "load"), "peak rates (step rule's grid)": ("base.py", "peak_rates"),
         "step rate (before: kinematics)": ("kinematics.py", "_step_rate"), "engine run": ("mujoco.py", "run"),
         "write the CSV": ("signals.py", "to_csv"), "whole command": ("cli.py", "main")}}
out = {{label: max((v[3] for (f, _, name), v in stats.items() if f.endswith(file) and name == func), default=0.0)
       for label, (file, func) in parts.items()}}
print("PROFILE " + json.dumps(out))
"""


#: Which heavy modules `mechval list` imported (issue 24: none; under 0.5 s).
LIST_IMPORTS = """
import sys, json
from mechval.harness.cli import main
main(["list"])
heavy = ("numpy", "pandas", "scipy", "mujoco", "pybullet", "exudyn")
print("IMPORTS " + json.dumps([m for m in heavy if m in sys.modules]))
"""


def python(tree: Path, code: str) -> tuple[str, float, float]:
    """Run code in a fresh interpreter on the tree's mechval: its output,
    wall time and CPU time (the process and its children)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", PRELUDE.format(here=str(HERE), tree=str(tree)) + code],
                          capture_output=True, text=True, cwd=tempfile.gettempdir())
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in (0, 1) or "Traceback" in done.stderr:     # 1: a run whose comparison failed
        raise SystemExit(f"failed ({done.returncode}) on {tree}: {done.stderr[-2000:]}")
    return done.stdout, wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def command(tree: Path, argv: list[str], repeats: int) -> tuple[float, float]:
    """Best wall time and the CPU time of that run of `mechval ARGV`."""
    runs = [python(tree, f"from mechval.harness.cli import main; main({argv!r})")[1:] for _ in range(repeats)]
    return min(runs)


def tagged(output: str, tag: str):
    return json.loads(next(line for line in output.splitlines() if line.startswith(tag))[len(tag) + 1:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=Path, default=HERE, help="the checkout whose mechval is measured")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-run", action="store_true", help="leave out `mechval run` (the longest part)")
    args = parser.parse_args()
    tree = args.tree.resolve()
    if not (tree / "core" / "__init__.py").is_file():
        raise SystemExit(f"{tree}: not a checkout of mechval")
    commit = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    print(f"mechval of {tree} (commit {commit}); load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as folder:
        csv = ["--csv", str(Path(folder) / "x.csv")]
        rows = [("mechval list", *command(tree, ["list"], args.repeats)),
                ("mechval " + " ".join(SIMULATE), *command(tree, SIMULATE + csv, args.repeats))]
        if not args.skip_run:
            rows.append(("mechval " + " ".join(RUN), *command(tree, RUN + ["--out", str(Path(folder) / "r")], 1)))
        print(f"\n{'command':<80} {'wall [s]':>9} {'CPU [s]':>8}")
        for name, wall, cpu in rows:
            print(f"{name:<80} {wall:>9.2f} {cpu:>8.2f}")

        print(f"\nheavy modules `mechval list` imports: {tagged(python(tree, LIST_IMPORTS)[0], 'IMPORTS') or 'none'}")

        profile = tagged(python(tree, PROFILE.format(argv=SIMULATE + csv))[0], "PROFILE")
        print(f"\nwhere one simulate's time goes (cProfile, cumulative, imports excluded) [s]")
        for label, seconds in profile.items():
            print(f"  {label:<40} {seconds:>7.3f}")

        print("\nposition solves of the general reference (the load's check, else instants solved)")
        for argv in (SIMULATE + csv, ["run", "jansen-leg", "--engine", "mujoco", "--quiet", "--out",
                                      str(Path(folder) / "c")]):
            solves = tagged(python(tree, COUNT.format(argv=argv))[0], "SOLVES")
            print(f"  mechval {' '.join(argv[:4]):<44} {len(solves):>2}: {solves}")
    print(f"load average {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()
