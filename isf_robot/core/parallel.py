"""Running a batch of independent tasks, here or in worker processes, that stops cleanly.

:func:`run_tasks` is the one loop behind every command that runs many episodes (``compare``,
``sweep``, the satellite study). With ``jobs > 1`` the tasks run in ``spawn`` worker processes
that ignore SIGINT: Ctrl-C (to the parent or to the whole process group) and SIGTERM reach the
parent only, which terminates every worker at once and raises :class:`Interrupted` carrying the
tasks that did finish, so the caller can report them marked as partial. No worker is left
behind, and a worker's error stops the batch with that error.
"""

from __future__ import annotations

import functools
import multiprocessing
import signal
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

__all__ = ["Interrupted", "Terminated", "run_tasks", "MAX_JOBS"]

T = TypeVar("T")
R = TypeVar("R")

MAX_JOBS = 256
"""Most worker processes :func:`run_tasks` starts."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that the same clean-up as for Ctrl-C runs."""


class Interrupted(KeyboardInterrupt):
    """A batch stopped by Ctrl-C or SIGTERM.

    Attributes:
        done: ``(task, result)`` of every task that finished, in completion order.
        terminated: The stop came from SIGTERM (exit status 143) rather than SIGINT (130).
        partial: Whatever summary the caller builds from ``done`` (set by the caller).

    """

    def __init__(self, done: list[tuple[Any, Any]], *, terminated: bool = False) -> None:
        super().__init__(f"interrupted after {len(done)} finished task(s)")
        self.done = done
        self.terminated = terminated
        self.partial: Any = None


def _worker_init() -> None:
    # The parent decides: it terminates the workers on Ctrl-C / SIGTERM.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _indexed(fn: Callable[[Any], Any], item: tuple[int, Any]) -> tuple[int, Any]:
    return item[0], fn(item[1])


def run_tasks(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    *,
    jobs: int = 1,
    on_result: Callable[[int, int, T, R], None] | None = None,
) -> list[tuple[T, R]]:
    """Run ``fn(task)`` for every task and return ``(task, result)`` in completion order.

    Args:
        fn: A module-level (picklable) function when ``jobs > 1``.
        tasks: Picklable tasks.
        jobs: Worker processes (1: run here, in order).
        on_result: Called as ``on_result(done, total, task, result)`` after each task.

    Raises:
        Interrupted: Ctrl-C or SIGTERM (as :class:`Terminated`) arrived; ``done`` holds what
            finished. Workers are terminated before it is raised.
        Exception: A task's own error (the other workers are terminated first).

    """
    tasks = list(tasks)
    jobs = int(jobs)
    done: list[tuple[T, R]] = []

    def keep(task: T, result: R) -> None:
        done.append((task, result))
        if on_result is not None:
            on_result(len(done), len(tasks), task, result)

    try:
        if jobs <= 1 or len(tasks) <= 1:
            for task in tasks:
                keep(task, fn(task))
        else:
            ctx = multiprocessing.get_context("spawn")
            pool = ctx.Pool(min(jobs, len(tasks)), initializer=_worker_init)
            try:
                for i, result in pool.imap_unordered(functools.partial(_indexed, fn), list(enumerate(tasks))):
                    keep(tasks[i], result)
            except BaseException:
                pool.terminate()
                pool.join()
                raise
            pool.close()
            pool.join()
    except Interrupted:
        raise
    except KeyboardInterrupt as exc:
        raise Interrupted(done, terminated=isinstance(exc, Terminated)) from None
    return done
