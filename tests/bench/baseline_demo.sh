#!/usr/bin/env bash
# Engine regression check across engine versions, for real: record MuJoCo
# baselines with an older release (default 3.3.7) in a throw-away virtual
# environment, then check the project's current MuJoCo against them and print
# what changed (per signal, per accuracy class). Then measure determinism:
# the committed baselines (saved in worker processes) against runs with one
# worker and one BLAS/OpenMP thread, and in-process with 4 Python threads at
# once. Needs PyPI and ~4 min.
#
#   bash tests/bench/baseline_demo.sh [OLD_VERSION]      KEEP=1 keeps the temp dir
#
# The check is expected to exit 1 (no baseline of the current version: it prints
# the comparison with OLD for information; the signals changed beyond 1e-9 of their
# peak); this script fails only when a step cannot run.
set -euo pipefail
OLD=${1:-3.3.7}
REPO=$(cd "$(dirname "$0")/../.." && pwd)
TMP=$(mktemp -d -t mechval-baseline-demo.XXXXXX)
[[ ${KEEP:-0} == 1 ]] && echo "keeping $TMP" || trap 'rm -rf "$TMP"' EXIT

# The project's pinned dependencies with mujoco replaced by the old release;
# the project itself without dependencies (its pin is the current MuJoCo).
mapfile -t DEPS < <(python3 - "$REPO/pyproject.toml" "$OLD" <<'PY'
import re, sys, tomllib
deps = tomllib.load(open(sys.argv[1], "rb"))["project"]["dependencies"]
for d in deps:
    print(f"mujoco=={sys.argv[2]}" if re.match(r"mujoco\b", d) else d)
PY
)
echo "== virtual environment with mujoco $OLD in $TMP/venv"
python3 -m venv "$TMP/venv"
"$TMP/venv/bin/pip" install -q "${DEPS[@]}" 2>&1 | grep -v "^WARNING: Location" || true
"$TMP/venv/bin/pip" install -q --no-deps -e "$REPO" 2>&1 | grep -v "^WARNING: Location" || true
"$TMP/venv/bin/python" -c "import mujoco; print('old:', mujoco.__version__)"
"$REPO/.venv/bin/python" -c "import mujoco; print('current:', mujoco.__version__)"

echo "== mechval baseline save --engine mujoco (mujoco $OLD)"
"$TMP/venv/bin/mechval" baseline save --engine mujoco --dir "$TMP/baselines" | tail -n 2

echo "== mechval baseline check --engine mujoco (current mujoco)"
status=0
"$REPO/.venv/bin/mechval" baseline check --engine mujoco --dir "$TMP/baselines" || status=$?
echo "== check exit status $status (1: no baseline of the current version; the comparison above says what changed)"
[[ $status -le 1 ]]

echo "== determinism: committed baselines, 1 worker, 1 BLAS/OpenMP thread"
cd "$REPO"
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
    .venv/bin/mechval baseline check --dir baselines --workers 1 | grep -E "signals:|baseline check" | sort | uniq -c
echo "== determinism: committed baselines, in one process, 4 Python threads at once"
.venv/bin/python - <<'PY'
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from mechval.harness import baseline as bl
from mechval.engines.registry import adapter, availability
from mechval.harness.runner import tasks_for
from mechval.scenarios import builtin_names, load

scenarios = [s for s in map(load, builtin_names()) if "hard" not in s.tags]
tasks = tasks_for(scenarios, [e for e, reason in availability().items() if not reason])

def verdicts(task):
    signals = adapter(task.engine).simulate(task.scenario, task.overrides)
    stored = bl.find(Path("baselines"), task.engine, signals.version, task.scenario.name, task.setting)
    return set(bl.compare_to_baseline(stored.signals, signals)["verdict"]) if stored else {"no baseline"}

with ThreadPoolExecutor(4) as pool:
    results = list(pool.map(verdicts, tasks))
print(f"{sum(r == {'identical'} for r in results)} of {len(results)} runs bit-identical to the baselines")
PY
