"""The per-scene tables of RESULTS.md ("Three strategies on each shipped scene"), regenerated.

    nice -n 19 python benchmarks/scene_tables.py [--episodes 20] [--jobs 2] \
        [--scenes panda_pole panda_shelf panda_moving panda_servo ur5e_pole] [--replace] [--no-write]

Runs ``isf-robot compare --scene S --episodes N --jobs K`` for every scene (nominal, cbf and isf on
seeds 0..N-1, each scene's shipped files and parameters) and writes, per scene, the comparison table
and the worst-episode table between the ``<!-- scene_tables:start -->`` / ``<!-- scene_tables:end -->``
markers of RESULTS.md (``--no-write``: print only). The figures other than wall times do not depend
on the machine. ``--replace``: only the named scenes' tables are measured and replaced, the others
kept as they are, and the section's first line says when the named ones were measured.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

from isf_robot.arm import load_scene  # noqa: E402
from isf_robot.arm.compare import SceneSpec, compare_strategies, format_table  # noqa: E402
from isf_robot.support.files import write_text_atomic  # noqa: E402

SCENES = ("panda_pole", "panda_shelf", "panda_moving", "panda_servo", "ur5e_pole")
START, END = "<!-- scene_tables:start -->", "<!-- scene_tables:end -->"


def worst_table(results: dict[str, Any]) -> list[str]:
    """Per strategy, over its episodes: the worst barrier and collisions, fallbacks, relaxations, tracking error."""
    lines = ["| strategy | worst min h [m] | worst collisions | fallbacks | relaxations | "
             "worst tracking error q99 [rad/s] | episodes with q99 <= d_bar | d_bar [rad/s] |",
             "|---|---|---|---|---|---|---|---|"]
    for name, res in results.items():
        eps = res["episodes"]
        cov = sum(1 for e in eps if e["tracking_error_q99"] <= e["d_bar"])
        lines.append(f"| {name} | {min(e['min_barrier'] for e in eps):.4f} | {max(e['collisions'] for e in eps)} | "
                     f"{sum(e['fallbacks'] for e in eps)} | {sum(e['relaxations'] for e in eps)} | "
                     f"{max(e['tracking_error_q99'] for e in eps):.3f} | {cov} of {len(eps)} | "
                     f"{eps[0]['d_bar']:.4f} |")
    return lines


def replaced(path: Path, scenes: list[str], parts: list[str], head: str) -> str:
    """The section of ``path`` with the ``### <scene>:`` tables of ``scenes`` replaced by ``parts``.

    The first line of the section (when the rest was measured) is kept, followed by ``head`` naming the
    scenes measured here.
    """
    text = path.read_text(encoding="utf-8")
    old = text.split(START, 1)[1].split(END, 1)[0].strip("\n")
    first, _, rest = old.partition("\n")
    blocks = ["### " + b for b in rest.split("\n### ")[1:]] if rest.lstrip().startswith("### ") else []
    new = {}
    for line in "\n".join(parts).split("\n### ")[0:]:
        name = line.removeprefix("### ").split(":", 1)[0]
        new[name] = ("### " + line.removeprefix("### ")).rstrip()
    out = [new.get(b.removeprefix("### ").split(":", 1)[0], b.rstrip()) for b in blocks]
    have = {b.removeprefix("### ").split(":", 1)[0] for b in blocks}
    out += [v for k, v in new.items() if k not in have]
    note = (head.replace(" by `", f" ({', '.join(scenes)} only) by `", 1).rstrip("`.")
            + f" --scenes {' '.join(scenes)} --replace`.")
    return "\n".join([first, note, "", "\n\n".join(out)]).rstrip()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--replace", action="store_true",
                    help="replace only these scenes' tables in the section, keep the others")
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args()
    load, t0 = os.getloadavg(), time.perf_counter()
    parts = []
    for name in args.scenes:
        comp = compare_strategies(SceneSpec(name=name), args.episodes, jobs=args.jobs,
                                  progress=lambda done, total, task, r: print(
                                      f"[{done}/{total}] {task.strategy} seed {task.seed}", file=sys.stderr))
        title = load_scene(name).config.description
        parts += [f"### {name}: {title}", "", "```",
                  f"isf-robot compare --scene {name} --episodes {args.episodes} --jobs {args.jobs}", "```", "",
                  "```", format_table(comp), "```", "", *worst_table(comp.as_dict()["results"]), ""]
    wall = time.perf_counter() - t0
    head = (f"Measured {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC on {cpu_model()} "
            f"(load average before {load[0]:.2f}, {wall / 60:.1f} min) by `python benchmarks/scene_tables.py "
            f"--episodes {args.episodes} --jobs {args.jobs}`.")
    body = "\n".join([head, "", *parts]).rstrip()
    if args.replace:
        body = replaced(ROOT / "RESULTS.md", args.scenes, parts, head)
    print(body)
    if not args.no_write:
        write_section(ROOT / "RESULTS.md", START, END, body, write_text_atomic)


if __name__ == "__main__":
    main()
