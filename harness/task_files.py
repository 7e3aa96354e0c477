"""Where the local pool's tasks and values pass between the main process
and the workers (`executors.LocalExecutor`, `pool_host.call`): a pair of
files per task, named by paths that any process of the run can open.

On Linux they are anonymous memory files (memfd_create) of the main
process, opened by the others through /proc/PID/fd/N: nothing is written
to any file system, and nothing outlives the main process, however it
ends. Elsewhere they are files of a temporary folder (TMPDIR), removed as
the batch ends (a run killed by SIGKILL leaves that folder behind).
"""

from __future__ import annotations

import os
import shutil
import tempfile


class TaskFiles:
    """A batch's task and value files, by task index."""

    def __init__(self):
        self.pid = os.getpid()
        self.memory = hasattr(os, "memfd_create") and os.path.isdir(f"/proc/{self.pid}/fd")
        self.folder = None if self.memory else tempfile.mkdtemp(prefix="mechval-values-")
        self.fds: dict[int, tuple[int, int]] = {}

    def paths(self, index: int) -> tuple[str, str]:
        """The task's file and its value's (made empty where they were used)."""
        if not self.memory:
            return tuple(os.path.join(self.folder, f"{index}.{kind}") for kind in ("task", "value"))
        self.release(index)
        self.fds[index] = (os.memfd_create(f"mechval-task-{index}"), os.memfd_create(f"mechval-value-{index}"))
        return tuple(f"/proc/{self.pid}/fd/{fd}" for fd in self.fds[index])

    def release(self, index: int) -> None:
        """The task's files are no longer needed."""
        if self.memory:
            for fd in self.fds.pop(index, ()):
                os.close(fd)
        else:
            for path in self.paths(index):
                if os.path.exists(path):
                    os.unlink(path)

    def close(self) -> None:
        for index in list(self.fds):
            self.release(index)
        if self.folder:
            shutil.rmtree(self.folder, ignore_errors=True)

    def __enter__(self) -> "TaskFiles":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
