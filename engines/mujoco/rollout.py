"""MuJoCo's rollout in pieces short enough for a stop signal to end the run
promptly, with the same states as one rollout.

Why: `mujoco.rollout.rollout` steps in one C call, and Python runs a
signal handler only between bytecodes of the main thread, so SIGINT or
SIGTERM waited for the whole rollout (10 s on fourbar-long-run, measured
here). Each piece continues exactly where the last one stopped: its
initial state is the last full physics state and its warm start the data's
`qacc_warmstart` after the last step (a rollout sets exactly these two from
its arguments, and zeroes the warm start when none is given). A rollout
clears MuJoCo's warning counters when it starts and, once a warning is
raised, repeats the last state to its end; the pieces keep that: after a
piece that raised one, the rest of the run repeats its last state.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np
from mujoco import rollout

#: Seconds of stepping per piece the piece length aims at: a stop signal
#: waits at most about this long (plus one piece's misjudgement).
PIECE_SECONDS = 0.1
#: Steps of the first piece, and the bounds of the later ones (a piece
#: costs some 0.1 ms besides its steps).
FIRST_PIECE, MIN_PIECE, MAX_PIECE = 1000, 100, 1_000_000


def rollout_in_pieces(m: mujoco.MjModel, d: mujoco.MjData, state0: np.ndarray, control: np.ndarray | None,
                      nstep: int, control_spec: int | None = None) -> np.ndarray:
    """(nstep, nstate) full physics states after each step from `state0`
    (`control`: (nstep, nu) or None; (nstep, size of `control_spec`) with
    a spec, e.g. controls and applied body forces), as `rollout.rollout`
    gives them for one trajectory."""
    spec = {} if control_spec is None else {"control_spec": control_spec}
    states = np.empty((nstep, len(state0)))
    state, warmstart, done, piece = state0, None, 0, FIRST_PIECE
    while done < nstep:
        n = min(piece, nstep - done)
        clock = time.perf_counter()
        states[done:done + n] = rollout.rollout(
            m, d, state[None], None if control is None else control[None, done:done + n], nstep=n,
            initial_warmstart=warmstart, **spec)[0][0]
        elapsed = time.perf_counter() - clock
        done += n
        state, warmstart = states[done - 1], d.qacc_warmstart.copy()[None]
        if any(w.number for w in d.warning):
            states[done:] = state
            break
        piece = int(np.clip(n * PIECE_SECONDS / max(elapsed, 1e-6), MIN_PIECE, MAX_PIECE))
    return states
