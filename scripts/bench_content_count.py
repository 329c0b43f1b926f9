"""How the bowl's sphere count (velma/perception/content.py ``count_spheres``) compares with
the truth on the final scenes of recorded runs.

For each run folder (its ``world_final.f64``: sim time then qpos; its ``launch_env.json``
gives the kitchen's ROCO_SEED and ROCO_POSE_SEED) and each of ``--seeds`` draws of the
Kinect's noise: the head camera's frame of the final scene as ag_ex renders it
(velma/executor/observer.py: 640 × 480, ``FRAMES_AVERAGED`` frames), the bowl localised,
its spheres counted. The truth from the simulation's state: the content spheres within the
bowl's inner radius of its axis, between its bottom and rim; of those, "in view" are the
ones of which a segmentation render of the same camera shows at least
``MIN_SPHERE_POINTS`` pixels. A run whose final scene has no bowl in view or an empty bowl
is listed and skipped.

Prints one line a look and a Markdown summary: looks whose seen count is below the spheres
in view (a sphere in view missed), above the truth (a sphere invented), and whose count
(seen + inferred behind the wall) is below or above the truth.

Usage: python scripts/bench_content_count.py RUN_DIR... [--seeds 3] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)
import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402

from shared.settings import Settings  # noqa: E402
from velma.executor.capture import WorldCapture  # noqa: E402  (velma chooses MuJoCo's GL first)
from velma.executor.observer import FRAMES_AVERAGED, CameraObserver  # noqa: E402
from velma.model.scene import PARTICLE_PREFIX, PARTICLE_RADIUS, load_kitchen  # noqa: E402
from velma.perception.content import MIN_SPHERE_POINTS, count_spheres  # noqa: E402
from velma.perception.segment import support_heights  # noqa: E402

if TYPE_CHECKING:
    import mujoco


@dataclass(frozen=True)
class Look:
    """One count of one run's final scene: ``truth`` spheres in the bowl, ``in_view`` of them
    in view, ``visible`` seen and ``hidden`` inferred by the counter."""

    run: str
    seed: int
    truth: int
    in_view: int
    visible: int
    hidden: int


def _kitchen_key(run: Path) -> tuple[int, int | None]:
    """The kitchen's seed and pose seed (shared/settings.py ``seed``, ``pose_seed``) of ``run``'s
    launch (0 and None when unset)."""
    env = json.loads((run / "launch_env.json").read_text())
    pose = env.get(Settings.env_name("pose_seed"))
    return int(env.get(Settings.env_name("seed")) or 0), int(pose) if pose else None


def _segment_pixels(observer: CameraObserver, data: mujoco.MjData, geoms: list[int]) -> npt.NDArray[np.int64]:
    """Pixels of each geom in ``geoms`` in a segmentation render of the head camera."""
    import mujoco  # after velma's imports, which choose its GL platform

    renderer = observer.kinect._renderer
    assert renderer is not None  # made by the capture before
    renderer.enable_segmentation_rendering()
    try:
        renderer.update_scene(data, camera=observer.kinect.camera_id)
        seg = renderer.render().copy()
    finally:
        renderer.disable_segmentation_rendering()
    ids = seg[..., 0][seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)]
    return np.array([int(np.count_nonzero(ids == g)) for g in geoms], dtype=np.int64)


def looks(run: Path, seeds: int, observers: dict[tuple[int, int | None], CameraObserver]) -> list[Look]:
    """The counts of ``run``'s final scene under ``seeds`` noise draws (empty when the bowl is
    not seen or holds nothing). Raises ``OSError`` for a folder without the files."""
    key = _kitchen_key(run)
    if key not in observers:
        observers[key] = CameraObserver(load_kitchen(seed=key[0], pose_seed=key[1]))
    ob = observers[key]
    model = ob.model
    scene = np.fromfile(run / "world_final.f64")
    bodies = [b for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX)]
    geoms = [model.geom(f"{model.body(b).name}_geom").id for b in bodies]
    bowl = ob.models["bowl"]
    out: list[Look] = []
    for seed in range(seeds):
        ob.rng = np.random.default_rng(seed)
        data = ob.load(WorldCapture.of(("bowl",), float(scene[0]), scene[1:]))
        frame = ob.kinect.capture(data, ob.rng, FRAMES_AVERAGED)
        points, colours, _ = frame.cloud()
        e = ob.localiser.localise(points, colours, frame.position, ["bowl"], support_heights(points))["bowl"]
        k = frame.intrinsics
        c = count_spheres(
            e, bowl, points, colours, frame.depth, frame.rgb, frame.position, frame.rotation,
            k.fx, k.cx, k.cy, ob.content_rgba, PARTICLE_RADIUS,
        )  # fmt: skip
        if c is None:
            print(f"{run}: the bowl is not seen", file=sys.stderr)
            return out
        base = data.xpos[model.body("bowl").id]
        rel = np.array([data.xpos[b] for b in bodies]) - base
        inside = (np.hypot(rel[:, 0], rel[:, 1]) < bowl.radius) & (rel[:, 2] > 0) & (rel[:, 2] < bowl.height)
        if not inside.any():
            print(f"{run}: the bowl is empty", file=sys.stderr)
            return out
        shown = _segment_pixels(ob, data, geoms) >= MIN_SPHERE_POINTS
        out.append(Look(run.name, seed, int(inside.sum()), int((inside & shown).sum()), c.visible, c.hidden))
    return out


def summary(all_looks: list[Look]) -> str:
    """The Markdown table of ``all_looks``."""
    n = len(all_looks)
    rows = [
        ("seen < in view (a sphere in view missed)", sum(x.visible < x.in_view for x in all_looks)),
        ("seen > truth (a sphere invented)", sum(x.visible > x.truth for x in all_looks)),
        ("seen + inferred < truth", sum(x.visible + x.hidden < x.truth for x in all_looks)),
        ("seen + inferred > truth", sum(x.visible + x.hidden > x.truth for x in all_looks)),
    ]
    scenes = len({x.run for x in all_looks})
    lines = [
        f"{n} looks ({scenes} final scenes × noise seeds)",
        "",
        "| looks where | of the looks |",
        "|---|---|",
    ]
    lines += [f"| {what} | {k} |" for what, k in rows]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders (world_final.f64, launch_env.json)")
    ap.add_argument("--seeds", type=int, default=3, help="draws of the Kinect's noise per scene")
    ap.add_argument("--out", type=Path, default=None, help="also write the Markdown report here")
    args = ap.parse_args(argv)
    if args.seeds < 1:
        print("roco: --seeds must be at least 1", file=sys.stderr)
        return 2
    missing = [r for r in args.runs if not (r / "world_final.f64").is_file()]
    if missing:
        print(f"roco: no world_final.f64 in {missing[0]}", file=sys.stderr)
        return 2
    observers: dict[tuple[int, int | None], CameraObserver] = {}
    all_looks: list[Look] = []
    for run in args.runs:
        for x in looks(run, args.seeds, observers):
            all_looks.append(x)
            seen = f"seen {x.visible} + {x.hidden} inferred"
            print(f"{x.run} seed {x.seed}: truth {x.truth}, in view {x.in_view}, {seen}", flush=True)
    for ob in observers.values():
        ob.close()
    report = benchlib.header(("mujoco",)) + "\n" + summary(all_looks)
    print(report)
    if args.out is not None:
        args.out.write_text(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
