"""Wall and CPU time of a child process: the one measurement every command benchmark makes.

No heavy import: the start-up benchmark imports it in its parent process.
"""

from __future__ import annotations

import resource
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ChildRun", "run_child"]


@dataclass(frozen=True)
class ChildRun:
    """One run of a command: seconds of wall time, CPU seconds (user + system), exit status, output."""

    wall_s: float
    cpu_s: float
    returncode: int
    stdout: str
    stderr: str


def run_child(
    argv: Sequence[str],
    *,
    cwd: Path | None = None,
    env: Mapping[str, str] | None = None,
    check: bool = False,
) -> ChildRun:
    """Run ``argv`` to completion; its wall time and the CPU time of it and its children.

    CPU time comes from ``getrusage(RUSAGE_CHILDREN)`` before and after, so it counts every
    process the command waited for (worker processes included). ``check`` raises on a
    non-zero exit status, as :func:`subprocess.run` does.

    Examples
    --------
    >>> import sys
    >>> r = run_child([sys.executable, "-c", "print('ok')"])
    >>> r.returncode, r.stdout.strip(), r.wall_s > 0
    (0, 'ok', True)
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run(
        list(argv),
        cwd=cwd,
        env=None if env is None else dict(env),
        capture_output=True,
        text=True,
        check=check,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return ChildRun(wall, cpu, res.returncode, res.stdout, res.stderr)
