"""What a new user waits for: the demo and a first run with a cold and a warm kernel cache, and the test suite.

Usage: ``python benchmarks/first_run_bench.py [--repeats 2] [--suite] [--out BENCHMARKS.md]``.

Each figure is a whole command (interpreter start, imports, run), timed from outside:

* ``isf-robot demo`` and ``isf-robot run --scene panda_pole --filter isf --duration 10``, each with
  numba's cache in a new empty folder (``NUMBA_CACHE_DIR``: the first run after an install, which
  compiles the kernels) and again with that folder filled (every later run), and the demo without
  the kernels (``ISF_ROBOT_JIT=0``);
* with ``--suite``: the README's test command (``pip install ".[test]" && pytest -q -n 2``) in a clone of the
  checkout that has no ``../shared`` beside it (a user's clone), in a new virtual environment (cold kernel caches,
  as in CI); the install is not timed.

Targets (issue "Clean clone, working wheel"): the demo under 10 s on a fresh install; the suite at
most 5 minutes on 2 cores. Only the section between ``<!-- first-run-bench:start -->`` and
``<!-- first-run-bench:end -->`` of the output file is rewritten.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import cpu_model, write_section

START = "<!-- first-run-bench:start -->"
END = "<!-- first-run-bench:end -->"
ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent


def timed(cmd: list[str], env: dict[str, str], cwd: Path) -> tuple[float, str]:
    """Wall time [s] of one command and its stderr (it must succeed)."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return wall, proc.stderr


def command_times(repeats: int, work: Path) -> dict[str, list[float]]:
    """Cold and warm figures of the demo and of one run, and the demo without kernels."""
    base = {k: v for k, v in os.environ.items() if k not in ("ISF_ROBOT_DATA", "NUMBA_CACHE_DIR", "ISF_ROBOT_JIT")}
    cmds = {
        "demo": [str(BIN / "isf-robot"), "demo"],
        "run": [str(BIN / "isf-robot"), "run", "--scene", "panda_pole", "--filter", "isf", "--duration", "10"],
    }
    out: dict[str, list[float]] = {}
    for rep in range(repeats):
        cache = work / f"numba-{rep}"
        env = {**base, "NUMBA_CACHE_DIR": str(cache)}
        # a fresh install: the demo first (it does not compile), then the first run (it compiles), then both again
        for key, name in (("demo cold", "demo"), ("run cold", "run"), ("run warm", "run"), ("demo warm", "demo")):
            wall, err = timed(cmds[name], env, work)
            out.setdefault(key, []).append(wall)
            out.setdefault(f"{key} compiled", []).append(float("compiling the fast kernels" in err))
            out.setdefault(f"{key} plain", []).append(float("runs the plain NumPy path" in err))
            print(f"  {key}: {wall:.1f} s", file=sys.stderr, flush=True)
        shutil.rmtree(cache, ignore_errors=True)
        plain, _ = timed(cmds["demo"], {**base, "ISF_ROBOT_JIT": "0"}, work)
        out.setdefault("demo plain", []).append(plain)
        print(f"  demo without kernels: {plain:.1f} s", file=sys.stderr, flush=True)
    return out


def suite_time(work: Path) -> tuple[float, str]:
    """The README's test command in a user's clone (no ../shared), in a fresh virtual environment: cold caches.

    ``pip install ".[test]"`` into a new environment (not timed), then ``pytest -q -n 2`` timed, with nothing of
    this script's environment that would change what the tests import (``PYTHONPATH``, the active environment) and
    numba's cache where a user's is (beside the installed package and the clone's sources: both new).
    """
    clone = work / "clone" / "isf_robot"
    clone.parent.mkdir()
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    venv = work / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    drop = ("ISF_ROBOT_DATA", "NUMBA_CACHE_DIR", "ISF_ROBOT_JIT", "PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env["PATH"] = os.pathsep.join((str(venv / "bin"), env.get("PATH", "")))
    env["VIRTUAL_ENV"] = str(venv)
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet", ".[test]"], cwd=clone, env=env,
                   check=True)
    t0 = time.perf_counter()
    proc = subprocess.run([str(venv / "bin" / "pytest"), "-q", "-n", "2", "-p", "no:cacheprovider"], cwd=clone,
                          env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    summary = (proc.stdout.strip().splitlines() or ["?"])[-1]
    if proc.returncode != 0:
        raise RuntimeError(f"the suite failed:\n{proc.stdout[-3000:]}")
    return wall, summary


def report(times: dict[str, list[float]], suite: tuple[float, str] | None, load0: tuple[float, ...]) -> str:
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    load = os.getloadavg()

    def med(key: str) -> str:
        return f"{statistics.median(times[key]):.1f}"

    lines = [
        "## First runs and the test suite (`benchmarks/first_run_bench.py`)",
        "",
        f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
        f"{platform.python_version()}. Date (UTC): {now}. Load average before / after: "
        f"{load0[0]:.2f} / {load[0]:.2f}.",
        "Whole commands (interpreter, imports, run), median of "
        f"{len(times['demo cold'])}; *cold*: numba's cache empty (the first run after an install), *warm*: every "
        "later run. Order per repeat, one cache: demo, run, run, demo. With a cold cache `run` compiles the "
        "kernels (and says so on stderr); the demo does not wait for the compiler: it runs the plain NumPy path "
        "(and says so).",
        "",
        "| command | cold cache [s] | warm cache [s] | without kernels (`ISF_ROBOT_JIT=0`) [s] |",
        "|---|---|---|---|",
        f"| `isf-robot demo` | {med('demo cold')} | {med('demo warm')} | {med('demo plain')} |",
        f"| `isf-robot run --scene panda_pole --filter isf --duration 10` | {med('run cold')} | {med('run warm')} "
        "| - |",
        "",
        f"Notices on stderr: cold runs that compiled {int(sum(times['run cold compiled']))} of "
        f"{len(times['run cold'])}, cold demos on the plain path {int(sum(times['demo cold plain']))} of "
        f"{len(times['demo cold'])}; warm demos that compiled anything (the demo uses the kernels the cache holds, "
        "the rest as written) "
        f"{int(sum(times['demo warm compiled']))} of {len(times['demo warm'])}, warm commands on the plain path "
        f"{int(sum(times['demo warm plain']) + sum(times['run warm plain']))}, warm runs that compiled "
        f"{int(sum(times['run warm compiled']))}.",
    ]
    if suite is not None:
        lines += ["", "`pytest -q -n 2` in a user's clone (no `../shared`), after `pip install \".[test]\"` into a new "
                  f"virtual environment (cold kernel caches; the install not timed): **{suite[0] / 60:.1f} min** "
                  f"({suite[1]}). Target: at most 5 min."]
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--suite", action="store_true", help="also time the test suite in a user's clone")
    p.add_argument("--out", default=str(ROOT / "BENCHMARKS.md"))
    p.add_argument("--no-write", action="store_true", help="print the section instead of writing it")
    args = p.parse_args()
    if args.repeats < 1:
        p.error(f"--repeats must be >= 1, got {args.repeats}")
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        times = command_times(args.repeats, work)
        suite = suite_time(work) if args.suite else None
    body = report(times, suite, load0)
    if not args.no_write:
        write_section(Path(args.out), START, END, body)
    print(body)


if __name__ == "__main__":
    main()
