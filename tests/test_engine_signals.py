"""A stop signal while a real engine is inside its solver: `mechval simulate`
exits 128 + signum within the bound, says so in one line and writes no CSV.

Exudyn turns an exception raised in a Python user function (where the
signal handler runs while Exudyn steps) into its own ModelError; MuJoCo's
rollout is one C call that no Python handler can interrupt. The command
runs as a subprocess in a session of its own; it announces, by a file, the
moment it enters the engine's solver (a wrapper around Exudyn's
`SolveDynamic` or MuJoCo's `rollout`), and the signal follows a little
later, while the solver runs. Linux only, as tests/test_faults.py.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import engine_or_skip
from mechval.scenarios import builtin_path

pytestmark = [pytest.mark.engine,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux process semantics")]

#: Seconds from the signal to the end of the command that the test accepts
#: (the requirement is about one second; the rest is slack for a loaded
#: machine, as tests/test_faults.py's STOP_WITHIN).
STOP_WITHIN = 2.0
#: Seconds inside the solver before the signal is sent.
INSIDE = 0.5

#: The command line with the engine's solver entry wrapped so that it
#: touches the file argv[1] when it starts; argv[2:] are the engine, the
#: scene and the rest of `mechval simulate`'s arguments.
ANNOUNCING_CLI = """
import sys
from pathlib import Path

ready = Path(sys.argv[1])
if sys.argv[2] == "exudyn":
    import exudyn
    holder, name = exudyn.MainSystem, "SolveDynamic"
else:
    from mujoco import rollout
    holder, name = rollout, "rollout"
original = getattr(holder, name)

def announced(*args, **kwargs):
    ready.touch()
    return original(*args, **kwargs)

setattr(holder, name, announced)
from mechval.harness import cli
sys.exit(cli.main(["simulate", "--engine", *sys.argv[2:]]))
"""


def long_scene(folder: Path) -> Path:
    """fourbar-seed spun at a constant 20 rad/s for 100 s (1001 samples):
    a run of tens of seconds in either engine, far longer than the test
    waits, and quick to load (the four-bar's closed form)."""
    text = builtin_path("fourbar-seed").read_text(encoding="utf-8")
    text = (text.replace('name = "fourbar-seed"', 'name = "fourbar-spun"')
            .replace("omega0 = 1.0", "omega0 = 20.0").replace("alpha = 1.0", "alpha = 0.0")
            .replace("end = 6.0", "end = 100.0").replace("samples = 601", "samples = 1001"))
    path = folder / "fourbar-spun.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("engine", ["exudyn", "mujoco"])
def test_a_signal_inside_the_engine_stops_simulate_at_once(tmp_path, engine, signum):
    engine_or_skip(engine)
    ready, csv = tmp_path / "inside-solver", tmp_path / "out" / "run.csv"
    csv.parent.mkdir()
    command = [sys.executable, "-c", ANNOUNCING_CLI, str(ready), engine, str(long_scene(tmp_path)),
               "--csv", str(csv)]
    with (tmp_path / "stderr.txt").open("w") as err:
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not ready.exists():
            assert process.poll() is None, (tmp_path / "stderr.txt").read_text()
            assert time.monotonic() < deadline, "the engine's solver never started"
            time.sleep(0.02)
        time.sleep(INSIDE)
        assert process.poll() is None, "the run ended before the signal"
        sent = time.monotonic()
        os.kill(process.pid, signum)
        status = process.wait(timeout=120)
        elapsed = time.monotonic() - sent
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    stderr = (tmp_path / "stderr.txt").read_text()
    assert status == 128 + signum, stderr
    assert stderr.strip() == f"mechval: stopped by {signal.Signals(signum).name}"
    assert elapsed < STOP_WITHIN, f"stopped {elapsed:.2f} s after the signal"
    assert not any(csv.parent.iterdir())
