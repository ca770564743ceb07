"""Running a batch of independent tasks, here, in worker processes or on Ray, that stops cleanly.

:func:`run_tasks` is the one loop behind every command that runs many episodes (``compare``,
``sweep``, the satellite study). Backends (:data:`BACKENDS`):

* ``processes`` (default): with ``jobs > 1`` the tasks run in ``spawn`` worker processes that
  ignore SIGINT: Ctrl-C (to the parent or to the whole process group) and SIGTERM reach the
  parent only, which terminates every worker at once and raises :class:`Interrupted` carrying
  the tasks that did finish, so the caller can report them marked as partial. No worker is left
  behind, and a worker's error stops the batch with that error.
* ``ray`` (optional extra ``ray``): each task is a Ray task with one CPU, at most ``jobs`` in
  flight. Without ``address`` a local Ray instance with ``jobs`` CPUs is started for the batch
  and shut down after it; with ``address`` (``"auto"`` or ``"HOST:PORT"``) the batch joins that
  cluster, whose nodes must have this package importable. Ctrl-C / SIGTERM stop the pending
  tasks (the local instance is shut down; on a cluster they are cancelled, force) and raise
  :class:`Interrupted` with what finished, as above; a task's error is re-raised as itself (not
  Ray's wrapper).

Tasks are matched to results by their index, so a backend returns the same ``(task, result)``
pairs as any other; only the completion order may differ.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from isf_robot.core.exceptions import ConfigError, IsfError

from .extras import install_hint
from .messages import one_line_warnings

__all__ = ["Interrupted", "Terminated", "run_tasks", "MAX_JOBS", "BACKENDS", "check_backend"]

T = TypeVar("T")
R = TypeVar("R")

MAX_JOBS = 256
"""Most worker processes :func:`run_tasks` starts."""

BACKENDS: tuple[str, ...] = ("processes", "ray")
"""Where :func:`run_tasks` runs the tasks (``--backend`` of the commands that use it)."""

RAY_MISSING = f"the ray backend needs Ray: {install_hint('ray')}; or use --backend processes"


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
    one_line_warnings()  # (as the command that started this worker prints them, if it does)


def _indexed(fn: Callable[[Any], Any], item: tuple[int, Any]) -> tuple[int, Any]:
    return item[0], fn(item[1])


def check_backend(backend: str, address: str | None = None) -> None:
    """Check a backend name (and that Ray is importable for ``ray``) before any task runs.

    Raises:
        ConfigError: Unknown backend, ``address`` without ``ray``, or Ray not installed.

    """
    if backend not in BACKENDS:
        raise ConfigError(f"unknown backend {backend!r}; valid backends: {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise ConfigError("--address goes with --backend ray (the address of a Ray cluster)")
    if backend == "ray":
        _import_ray()


class RayStartError(IsfError):
    """Ray could not be started or joined (one line on the command line, exit status 2)."""


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise ConfigError(RAY_MISSING) from None
    return ray


def run_tasks(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    *,
    jobs: int = 1,
    on_result: Callable[[int, int, T, R], None] | None = None,
    backend: str = "processes",
    address: str | None = None,
) -> list[tuple[T, R]]:
    """Run ``fn(task)`` for every task and return ``(task, result)`` in completion order.

    Args:
        fn: A module-level (picklable) function when ``jobs > 1`` or on Ray.
        tasks: Picklable tasks.
        jobs: Worker processes (1: run here, in order), or Ray tasks in flight.
        on_result: Called as ``on_result(done, total, task, result)`` after each task.
        backend: One of :data:`BACKENDS`.
        address: Ray cluster to join (``ray`` only); default a local instance with ``jobs`` CPUs.

    Raises:
        ConfigError: Bad backend (see :func:`check_backend`).
        Interrupted: Ctrl-C or SIGTERM (as :class:`Terminated`) arrived; ``done`` holds what
            finished. Workers are terminated (Ray tasks cancelled) before it is raised.
        Exception: A task's own error (the other workers are terminated first).

    """
    check_backend(backend, address)
    tasks = list(tasks)
    jobs = int(jobs)
    if not 1 <= jobs <= MAX_JOBS:
        raise ConfigError(f"jobs must be between 1 and {MAX_JOBS}, got {jobs}")
    done: list[tuple[T, R]] = []

    def keep(task: T, result: R) -> None:
        done.append((task, result))
        if on_result is not None:
            on_result(len(done), len(tasks), task, result)

    try:
        if backend == "ray":
            _run_ray(fn, tasks, jobs, address, keep)
        elif jobs <= 1 or len(tasks) <= 1:
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


def _set_sigterm(handler: Any) -> None:
    if threading.current_thread() is threading.main_thread():  # signal.signal works there only
        signal.signal(signal.SIGTERM, handler)


def _run_ray(fn: Callable[[Any], Any], tasks: list[Any], jobs: int, address: str | None,
             keep: Callable[[Any, Any], None]) -> None:
    """The Ray backend of :func:`run_tasks`: at most ``jobs`` tasks in flight, results by index."""
    ray = _import_ray()
    started = not ray.is_initialized()
    if started:
        opts: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False, "logging_level": "error"}
        term = signal.getsignal(signal.SIGTERM)  # ray.init replaces the driver's SIGTERM handler
        try:
            if address is None:  # a private instance, even when RAY_ADDRESS names a cluster
                saved = os.environ.pop("RAY_ADDRESS", None)
                try:
                    ray.init(num_cpus=jobs, **opts)
                finally:
                    if saved is not None:
                        os.environ["RAY_ADDRESS"] = saved
            else:
                ray.init(address=address, **opts)
        except (KeyboardInterrupt, ConfigError):
            raise
        except Exception as exc:  # noqa: BLE001 - Ray's own start-up errors carry no common type
            where = f"join the Ray cluster at {address}" if address is not None else "start a local Ray instance"
            raise RayStartError(f"could not {where}: {type(exc).__name__}: {exc}") from None
        finally:
            if term is not None:
                _set_sigterm(term)
    hit: list[int] = []
    term = signal.getsignal(signal.SIGTERM)
    if callable(term):  # Ray's wait turns any exception of a signal handler into a bare KeyboardInterrupt

        def on_term(signum: int, frame: Any) -> None:
            hit.append(signum)
            term(signum, frame)

        _set_sigterm(on_term)
    remote = ray.remote(num_cpus=1, max_retries=0)(_indexed)
    pending: list[Any] = []
    try:
        nxt = 0
        while nxt < len(tasks) or pending:
            while nxt < len(tasks) and len(pending) < jobs:
                pending.append(remote.remote(fn, (nxt, tasks[nxt])))
                nxt += 1
            ready, pending = ray.wait(pending, num_returns=1)
            for ref in ready:
                try:
                    i, result = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:
                    cause = getattr(exc, "cause", None)
                    if isinstance(cause, BaseException):
                        raise cause from None
                    raise
                keep(tasks[i], result)
    except BaseException as exc:
        # A private instance: ray.shutdown() below stops its workers. Cancelling there too raced with
        # the replies of tasks a terminal's Ctrl-C had already ended (the whole process group gets it)
        # and crashed the driver inside Ray ("Tried to complete task that was not pending", exit 1,
        # nothing kept); seen once in CI. A cluster keeps running after shutdown: cancel there.
        for ref in pending if not started or address is not None else ():
            try:
                ray.cancel(ref, force=True)
            except Exception:  # noqa: BLE001 - already finished or gone
                pass
        if hit and isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Terminated):
            raise Terminated() from None  # SIGTERM, whatever Ray made of its handler's exception
        raise
    finally:
        if callable(term):
            _set_sigterm(term)
        if started:
            ray.shutdown()
