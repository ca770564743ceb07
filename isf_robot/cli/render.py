"""``isf-robot render``: a video (GIF/MP4) or one PNG frame of an arm run, rendered offscreen.

The episode is the one ``isf-robot run`` simulates with the same flags; frames come from
:class:`isf_robot.arm.render.VideoRecorder` (robot orange while the filter is on, a banner with
the time and mode). The OpenGL backend is chosen before MuJoCo is imported
(:func:`isf_robot.arm.render.select_gl`: ``MUJOCO_GL`` if set, else EGL, else OSMesa); where none
works the command fails with one line saying why.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from isf_robot.cli.arm import _add_filter_args, _add_scene_args, _check_seed, _params, _simulation, _spec
from isf_robot.cli.arm_team import COORDINATION_HELP, check_coordination
from isf_robot.core.exceptions import ConfigError
from isf_robot.core.strategies import strategy_names

__all__ = ["register", "handle"]


def register(sub: Any) -> None:
    """Register ``render`` on the ``isf-robot`` subparsers."""
    p = sub.add_parser(
        "render", help="render an arm run offscreen to a GIF, MP4 or PNG",
        description="Simulate one episode (as `isf-robot run`) and render it offscreen with MuJoCo: "
                    "a .gif or .mp4 video, or one .png frame. The robot is orange while the filter is on. "
                    "Visual geoms are drawn; collision geoms of bodies that have visual geoms are hidden "
                    "(--show-collision draws them); a sky is added when the model has none.")
    _add_scene_args(p)
    p.add_argument("--filter", choices=strategy_names(), default="isf", help="strategy (default isf)")
    p.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    p.add_argument("--coordination", choices=("central", "decentral"), default=None, help=COORDINATION_HELP)
    _add_filter_args(p)
    p.add_argument("-o", "--output", type=Path, required=True, metavar="PATH",
                   help="output file: .gif, .mp4 (needs the 'video' extra) or .png (one frame)")
    p.add_argument("--fps", type=float, default=20.0, help="video frames per second (default 20)")
    p.add_argument("--speed", type=float, default=1.0, help="simulated seconds per video second (default 1)")
    p.add_argument("--width", type=int, default=480, help="frame width [px] (default 480)")
    p.add_argument("--height", type=int, default=360, help="frame height [px] (default 360)")
    p.add_argument("--at", type=float, default=None, metavar="S",
                   help=".png: time of the frame [s] (default: the first step with the filter on)")
    g = p.add_argument_group("camera and drawing (default: a free camera framing the arm at the first frame, the "
                             "obstacles and the goals, from the front-left and above)")
    g.add_argument("--camera", metavar="NAME", default=None,
                   help="a named camera of the model instead of the free camera")
    g.add_argument("--azimuth", type=float, default=None, metavar="DEG",
                   help="free camera's azimuth [deg] (default 140)")
    g.add_argument("--elevation", type=float, default=None, metavar="DEG",
                   help="free camera's elevation [deg], negative looks down (default -22)")
    g.add_argument("--distance", type=float, default=None, metavar="M",
                   help="free camera's distance from the lookat point [m] (default: fitted)")
    g.add_argument("--lookat", default=None, metavar="X,Y,Z",
                   help="point the free camera looks at [m] (default: fitted with the distance)")
    g.add_argument("--show-collision", action="store_true",
                   help="also draw the collision geoms of bodies that have visual geoms (hidden by default)")
    p.set_defaults(handler=handle)


def handle(args: argparse.Namespace) -> int:
    """Check the output, choose the GL backend, simulate with a VideoRecorder, report."""
    _check_seed(args)
    from isf_robot.arm.camera import View, camera_id, parse_lookat
    from isf_robot.arm.render import VideoRecorder

    view = View(camera=args.camera, azimuth=args.azimuth, elevation=args.elevation, distance=args.distance,
                lookat=None if args.lookat is None else parse_lookat(args.lookat))  # bad values fail first
    if "mujoco" not in sys.modules:  # MuJoCo reads MUJOCO_GL once, when first imported
        from isf_robot.arm.render import select_gl

        select_gl()

    video = VideoRecorder(args.output, fps=args.fps, width=args.width, height=args.height, speed=args.speed,
                          at=args.at, view=view, show_collision=args.show_collision)
    scene = _spec(args).load()
    check_coordination(args, scene)
    if view.camera is not None:
        camera_id(scene.model, view.camera)  # an unknown name fails before the episode runs
    sim = _simulation(args, scene, observers=[video], **_params(args, scene))
    end = sim.control_steps(args.duration) * sim.control_period
    if args.at is not None and args.at > end + 1e-9:
        raise ConfigError(f"--at {args.at:g} s is past the run's end ({end:g} s): give a time within it")
    wall = time.perf_counter()
    res = sim.run(args.duration)
    wall = time.perf_counter() - wall
    n = len(video.frame_times)
    rate = n / video.render_s if video.render_s > 0 else float("nan")
    way = f" {sim.coordination}" if scene.arms else ""
    print(f"wrote {args.output}: {n} frame(s) of {args.width} x {args.height} from {res.metrics.duration_s:.2f} s "
          f"simulated ({scene.name}, {args.filter}{way}, seed {args.seed}); rendering {rate:.1f} frames/s, "
          f"{wall:.2f} s in all", file=sys.stderr)
    return 0
