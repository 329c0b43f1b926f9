"""Robustness benchmark: the pour over N seeds with the jar and bowl poses randomised (±2 cm in
x and y, ±10° about the vertical; velma/model/scene.py ``scene_perturbation``), printed as a
table: per seed the perturbation, the outcome, the spheres in the bowl and the wall time, then
the success rate.

Two modes:

- ``fleet`` (default): ``roco run "pour the jar into the bowl" --seed K --pose-seed K``, the
  whole system (router, recorder, six agent processes, the loop process) planning from what
  ag_ex observes. The spheres in the bowl are the simulation's truth at the run's last camera
  Observation of the bowl (``ag_ex_perception.jsonl``, velma/executor/perception_log.py),
  shown beside what the camera counted there (what a_ta judged by); in a ground-truth run
  (``ROCO_PERCEPTION=truth``) both are the last L_SD Observation's. After the table: the
  camera's localisation error over every Observation of every run (per object and overall,
  mm p50 / p95 / max), the observations in which a requested object was not seen, and the
  content count's error against the truth.
- ``script``: the robot alone (velma/scenario.py ``pour_script`` on the threaded executor,
  aimed at the observed poses as the agents' plan is; no agents). The spheres in the bowl are
  the simulation's truth at the end, beside the last Observation's count.

Success: every command succeeded (grasps by contact and friction) and ≥ ``--min-share``
(default 90 %) of the spheres ended in the bowl.

Verdict against truth: per seed the verdict (fleet: the task's outcome, a_ta's content check
on what the camera saw, services/agents/task_executor/verdict.py; script: a_ta's verdict on the
last Observation as a second look, there being no a_ta) beside the truth (the spheres the
simulation holds in the bowl, the same ``--min-share`` of the content); the summary says in how
many seeds they agree, and the script exits 1 when any disagrees. The camera's count is shown
as seen + inferred (the spheres inferred behind the bowl's near wall, not seen).

Planted failures (fleet mode, ``--planted N``): after the plain seeds, N more seeds whose
world starts with ``--removed`` (default 3) of the 18 spheres taken out of the jar and laid on
the floor behind the robot, out of its reach and the head camera's view
(``ROCO_CONTENT_REMOVED``, velma/model/scene.py ``remove_content``): the pour then cannot put
more than 15 of 18 (83 %) in the bowl, a failure by the truth, which the verdict must see. Each
planted run is read back from its folder before it counts: the fleet was given the setting
(``launch_env.json``), the world started with the spheres out (the first Observation's truth:
the jar holds 18 − k, k in no container) and they stayed out (``world_final.f64``, the world's
last ``qpos``: each removed sphere still on the floor where it was laid). Every run is checked
to have poured (ag_ex's ledger holds a ``tilt`` that ended ok), so the wall time shown is a
pour's, and a verdict is a pour's verdict; the task's own time (command to outcome) is shown
beside it. The verdicts are then tabled against the truth as a confusion matrix, and the
script exits 1 when a verdict disagrees, a planted setup was not taken or a run did not pour.

Beside it, the number of commands during which the robot touched itself
(``CommandResult.self_contacts``; Velma's links collide with each other in the simulation,
docs/executor.md).

Usage: ``python scripts/bench_pour_seeds.py [--mode fleet|script] [--seeds 20] [--first 1]
[--planted 0] [--removed 3]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)
import numpy as np  # noqa: E402

from services.report.model import PerceptionRow  # noqa: E402
from shared.fipa_codec.languages.l_hc import CONTENT_SHARE_REQUIRED  # noqa: E402
from shared.settings import Settings  # noqa: E402
from velma.model.scene import (  # noqa: E402
    N_PARTICLES,
    PARTICLE_RADIUS,
    REMOVED_AT,
    REMOVED_SPACING,
    load_kitchen,
    particle_names,
    scene_perturbation,
)


@dataclass
class Outcome:
    ok: bool
    inside: int | None
    """Spheres truly in the bowl at the end (fleet mode with the camera: the simulation's
    count at the last Observation of the bowl)."""
    total: int | None
    detail: str
    wall: float
    touched: int = 0
    """Commands during which the robot touched itself (self-collision is on: docs/executor.md)."""
    counted: int | None = None
    """Spheres the last Observation reported in the bowl (the camera's count, or the truth)."""
    inferred: int | None = None
    """Of ``counted``, the spheres inferred behind the bowl's wall, not seen (None: not split)."""
    verdict: bool | None = None
    """The task's verdict: True succeeded, False failed (module docstring)."""
    perception: list[PerceptionRow] = field(default_factory=list)
    """The run's camera Observations beside the truth (fleet mode)."""
    removed: int = 0
    """Spheres taken out of the jar before the run (a planted failure; module docstring)."""
    problems: list[str] = field(default_factory=list)
    """Why this run does not count as a measured pour: its planted setup not taken, no pour."""
    task_s: float | None = None
    """The task's time, the command to its outcome (fleet mode; the wall time includes the
    fleet's start and stop)."""


def run_fleet(seed: int, runs_dir: Path, realtime: bool, removed: int = 0) -> Outcome:
    """One ``roco run`` with ``--seed seed --pose-seed seed``, ``removed`` spheres taken out of
    the jar first (module docstring). A run that succeeded while an agent counted anything
    refused, not understood or against its protocol (its ``counters.json``,
    services/bench/setup_check.py) is not a success: its detail says why. The run folder is
    read back: :func:`setup_problems`."""
    from services.bench.setup_check import SetupRefused, check_run_folder
    from services.report import build_report

    t0 = time.time()
    before = set(runs_dir.glob("*")) if runs_dir.exists() else set()
    cmd = [
        sys.executable, "-m", "services.cli", "run", "pour the jar into the bowl", "--quiet",
        "--runs-dir", str(runs_dir), "--seed", str(seed), "--pose-seed", str(seed),
    ]  # fmt: skip
    if realtime:
        cmd.append("--realtime")
    env = dict(os.environ)
    env.pop(REMOVED_VAR, None)
    if removed:
        env[REMOVED_VAR] = str(removed)
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False, env=env)
    wall = time.time() - t0
    new = sorted(set(runs_dir.glob("*")) - before)
    if not new:
        why = f"no run folder: {proc.stderr.strip()[-200:]}"
        return Outcome(False, None, None, why, wall, removed=removed, problems=[why])
    report = build_report(new[-1])
    c = report.content
    detail = report.header.detail or ("succeeded" if proc.returncode == 0 else "failed")
    touched = sum(e.kind == "self_contact" for e in report.events)
    truth = [
        r.content_truth for r in report.perception if r.object == c.container and r.content_truth is not None
    ]
    inside = truth[-1] if truth else c.inside
    ok = proc.returncode == 0
    if ok:
        try:
            check_run_folder(new[-1], "the agents")
        except SetupRefused as exc:
            ok, detail = False, str(exc)
    return Outcome(
        ok,
        inside,
        c.total,
        f"{detail} ({new[-1].name})",
        wall,
        touched,
        counted=c.inside,
        inferred=c.inferred,
        verdict=report.header.succeeded,
        perception=list(report.perception),
        removed=removed,
        problems=setup_problems(new[-1], seed, removed, list(report.perception)),
        task_s=report.header.task_duration_s,
    )


REMOVED_VAR = Settings.env_name("content_removed")
"""The variable that takes spheres out of the jar in the world process (shared/settings.py)."""


def setup_problems(run: Path, seed: int, removed: int, perception: list[PerceptionRow]) -> list[str]:
    """Why the run folder ``run`` is not a pour of the setup asked for (module docstring): the
    fleet not given ``removed``, the world's first Observation not showing the jar holding
    ``N_PARTICLES − removed`` with ``removed`` in no container, a removed sphere not on the
    floor where it was laid at the end, or no ``tilt`` that ended ok in ag_ex's ledger. Empty:
    the setup was taken and the robot poured."""
    problems = []
    launched = run / "launch_env.json"
    given = json.loads(launched.read_text()).get(REMOVED_VAR, "0") if launched.exists() else "(no file)"
    if given != (str(removed) if removed else "0"):
        problems.append(f"{REMOVED_VAR}={given} in launch_env.json, not {removed}")
    first = next((r for r in perception if r.object == "jar" and r.content_truth is not None), None)
    if first is None:
        problems.append("no Observation of the jar")
    elif first.content_truth != N_PARTICLES - removed or (first.outside_truth or 0) != removed:
        problems.append(
            f"the world started with {first.content_truth} in the jar and {first.outside_truth} "
            f"outside, not {N_PARTICLES - removed} and {removed}"
        )
    if removed:
        problems.extend(_removed_stayed(run, seed, removed))
    ledger = run / "ag_ex_ledger.jsonl"
    entries = [json.loads(line) for line in ledger.read_text().splitlines()] if ledger.exists() else []
    if not any(
        e.get("event") == "end" and e.get("command") == "tilt" and e.get("outcome") == "ok" for e in entries
    ):
        problems.append("the robot did not pour (no tilt ended ok in ag_ex_ledger.jsonl)")
    return problems


def _removed_stayed(run: Path, seed: int, removed: int) -> list[str]:
    """Problems with the removed spheres at the run's end (``world_final.f64``: the time and
    the world's ``qpos``): each must lie on the floor within 1 cm of where it was laid."""
    import mujoco

    final = run / "world_final.f64"
    if not final.exists():
        return ["no world_final.f64: the removed spheres' end not known"]
    model = load_kitchen(N_PARTICLES, seed, seed)
    data = mujoco.MjData(model)
    data.qpos[:] = np.fromfile(final, dtype=np.float64)[1:]
    mujoco.mj_kinematics(model, data)
    out = []
    for k, name in enumerate(particle_names()[N_PARTICLES - removed :]):
        laid = np.array([REMOVED_AT[0], REMOVED_AT[1] + k * REMOVED_SPACING, PARTICLE_RADIUS])
        moved = float(np.linalg.norm(data.xpos[model.body(name).id] - laid))
        if moved > 0.01:
            out.append(f"{name} ended {moved * 1000:.0f} mm from where it was laid")
    return out


def perception_summary(rows: list[PerceptionRow]) -> list[str]:
    """Lines summarising the camera's Observations of all runs (module docstring)."""
    if not rows:
        return ["No camera Observations (a ground-truth run)."]

    def stats(values: list[float]) -> str:
        a = np.asarray(values)
        return f"{np.percentile(a, 50):.1f} / {np.percentile(a, 95):.1f} / {a.max():.1f}"

    seen = [r for r in rows if r.seen and r.error_mm is not None]
    lines = [
        f"Localisation error, mm (p50 / p95 / max), over {len(seen)} objects seen in the runs' Observations:"
    ]
    for name in sorted({r.object for r in seen}):
        errors = [r.error_mm for r in seen if r.object == name and r.error_mm is not None]
        lines.append(f"- {name}: {stats(errors)} ({len(errors)} observations)")
    lines.append(f"- all: {stats([r.error_mm for r in seen if r.error_mm is not None])}")
    unseen = [r for r in rows if not r.seen]
    reasons = sorted({r.reason or "?" for r in unseen})
    lines.append(f"Requested but not seen: {len(unseen)} of {len(rows)} ({'; '.join(reasons) or 'none'}).")
    for name in sorted({r.object for r in rows if r.content_truth is not None}):
        counts = [
            r.content - r.content_truth
            for r in rows
            if r.object == name and r.content is not None and r.content_truth is not None
        ]
        if counts:
            lines.append(
                f"Content count − truth, {name}, over {len(counts)} observations: "
                f"{min(counts):+d} … {max(counts):+d}, mean {np.mean(counts):+.2f}."
            )
    outside = [
        (r.outside, r.outside_truth) for r in rows if r.outside is not None and r.outside_truth is not None
    ]
    if outside:
        missed = sum(1 for seen, truth in outside if seen != truth)
        lines.append(
            "Content seen outside every container: differs from the truth in "
            f"{missed} of {len(outside)} object observations "
            f"(seen {sum(o for o, _ in outside if o)}, true {sum(t for _, t in outside if t)} in all)."
        )
    return lines


def run_script(seed: int) -> Outcome:
    """The scripted pour on the threaded executor, the pour aimed at the observed bowl."""
    from shared.fipa_codec.languages.l_ex import CommandResult
    from shared.fipa_codec.languages.l_sd import Observation
    from velma.executor import Executor
    from velma.executor.ground_truth import GroundTruth
    from velma.scenario import run_pour

    t0 = time.time()
    ex = Executor(realtime=False, seed=seed, pose_seed=seed)
    ex.start()
    try:
        _, results = run_pour(ex.submit)
    finally:
        ex.stop()
    wall = time.time() - t0
    failed = next((r for r in results if isinstance(r, CommandResult) and not r.ok), None)
    final = results[-1]
    counted = total = inferred = None
    if isinstance(final, Observation):
        bowl = next((o for o in final.objects if o.name == "bowl"), None)
        counted, total = (bowl.particles_inside if bowl else None), final.total_particles
        inferred = bowl.particles_inferred if bowl else None
    inside = GroundTruth(ex.rt.model).particles_inside(ex.rt.data, "bowl")
    touched = sum(isinstance(r, CommandResult) and bool(r.self_contacts) for r in results)
    detail = "all commands succeeded" if failed is None else f"{failed.command} failed: {failed.reason}"
    verdict = failed is None and isinstance(final, Observation) and content_verdict(final)
    return Outcome(
        failed is None,
        inside,
        total,
        detail,
        wall,
        touched,
        counted=counted,
        inferred=inferred,
        verdict=verdict,
    )


def content_verdict(obs: object) -> bool:
    """a_ta's verdict on ``obs`` (an L_SD Observation) as the pour's content check's second
    look (services/agents/task_executor/verdict.py ``judge``): True when it goes on, so the
    task succeeds. Script mode has no a_ta, so no first look."""
    from services.agents.task_executor.verdict import Answer, Do, Step, judge
    from shared.fipa_codec.languages.l_hfsm import CheckContent, PlanNode

    check = CheckContent(container="bowl", min_fraction=CONTENT_SHARE_REQUIRED)
    step = Step("pour/check_bowl", PlanNode(name="check_bowl", action=check), second_view=2)
    return judge(step, Answer(True, obs, "inform", "inform"), False).do is Do.NEXT  # type: ignore[arg-type]


def truth_verdict(out: Outcome, min_share: float) -> bool:
    """What the verdict should be: the spheres truly in the bowl are ≥ ``min_share`` of the
    content (False when they were not observed)."""
    return out.inside is not None and bool(out.total) and out.inside >= min_share * (out.total or 0)


def camera_count(out: Outcome) -> str:
    """The camera's count as "seen + inferred" ("—": none; a count not split: itself)."""
    if out.counted is None:
        return "—"
    if out.inferred is None:
        return str(out.counted)
    return f"{out.counted - out.inferred} + {out.inferred}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mode", choices=("fleet", "script"), default="fleet")
    ap.add_argument("--seeds", type=int, default=20, help="how many seeds")
    ap.add_argument("--first", type=int, default=1, help="first seed")
    ap.add_argument(
        "--planted",
        type=int,
        default=0,
        help="fleet mode: this many more seeds, after --seeds, with --removed spheres taken out of the jar",
    )
    ap.add_argument(
        "--removed", type=int, default=3, help="spheres taken out of the jar in a planted seed (of 18)"
    )
    ap.add_argument("--min-share", type=float, default=0.9, help="share of spheres that counts as success")
    ap.add_argument("--realtime", action="store_true", help="fleet mode: pace the loop to wall time")
    ap.add_argument("--runs-dir", type=Path, default=None, help="fleet mode: where run folders go")
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="also write the output to this Markdown file, once every seed ran: "
        "docs/bench/pour_seeds_fleet.md (fleet mode)",
    )
    args = ap.parse_args()
    if args.planted and args.mode != "fleet":
        ap.error("--planted: fleet mode only (the world process takes the spheres out)")
    if not 0 < args.removed <= N_PARTICLES:
        ap.error(f"--removed: 1..{N_PARTICLES}")
    with benchlib.recorded(args.out):
        return measure(args)


def measure(args: argparse.Namespace) -> int:
    """Run and print the seeds ``args`` asks for (:func:`main`'s options)."""
    runs_dir = args.runs_dir or Path(tempfile.mkdtemp(prefix="roco-seeds-"))
    plain_end = args.first + args.seeds
    last = plain_end + args.planted - 1
    planted = f" ({plain_end}..{last} with {args.removed} spheres removed)" if args.planted else ""
    print(f"# Pour robustness, {args.mode} mode, seeds {args.first}..{last}{planted}\n")
    print(benchlib.header(("mujoco", "pin")), end="")
    if args.mode == "fleet":
        print(f"- Run folders: {runs_dir}")
    print(
        "\n| seed | planted | jar dx, dy (mm), yaw (°) | bowl dx, dy (mm), yaw (°) | spheres in bowl | share "
        "| camera: seen + inferred | success | verdict | truth | robot touched itself (commands) | wall s "
        "| task s | detail |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows: list[PerceptionRow] = []
    successes = touched = agree = 0
    shares: list[float] = []
    matrix = {(v, t): 0 for v in (True, False) for t in (True, False)}
    not_counted: list[str] = []
    for seed in range(args.first, last + 1):
        p = scene_perturbation(seed)
        removed = args.removed if seed >= plain_end else 0
        out = run_fleet(seed, runs_dir, args.realtime, removed) if args.mode == "fleet" else run_script(seed)
        share = out.inside / out.total if out.inside is not None and out.total else 0.0
        ok = out.ok and share >= args.min_share
        successes += ok
        truth = truth_verdict(out, args.min_share)
        agree += out.verdict is truth
        if out.problems:
            not_counted.append(f"seed {seed}: {'; '.join(out.problems)} ({out.detail})")
        elif out.verdict is not None:
            matrix[(out.verdict, truth)] += 1
        touched += out.touched > 0
        shares.append(share)
        rows.extend(out.perception)

        def pert(o: object) -> str:
            return f"{o.dx * 1000:+.0f}, {o.dy * 1000:+.0f}, {o.yaw * 57.2958:+.1f}"  # type: ignore[attr-defined]

        inside = f"{out.inside}/{out.total}" if out.inside is not None else "not observed"
        task = "—" if out.task_s is None else f"{out.task_s:.0f}"
        print(
            f"| {seed} | {f'{removed} removed' if removed else '—'} | {pert(p.jar)} | {pert(p.bowl)} | "
            f"{inside} | {share * 100:.0f} % | {camera_count(out)} | {'yes' if ok else 'NO'} | "
            f"{_said(out.verdict)} | {_said(truth)}{'' if out.verdict is truth else ' (DISAGREES)'} | "
            f"{out.touched} | {out.wall:.0f} | {task} | {out.detail} |",
            flush=True,
        )
    n = args.seeds + args.planted
    print(
        f"\nSuccess (all commands ok and ≥ {args.min_share * 100:.0f} % of the spheres in the bowl): "
        f"{successes} of {n}; mean share {sum(shares) / n * 100:.1f} %, lowest {min(shares) * 100:.0f} %; "
        f"the robot touched itself in {touched} of {n} runs."
    )
    print(
        f"Verdict matches truth: {agree} of {n} (truth: ≥ {args.min_share * 100:.0f} % of the spheres "
        "really in the bowl, from the simulation's state)."
    )
    print("\n" + "\n".join(confusion(matrix, args.min_share, not_counted)))
    if args.mode == "fleet":
        print("\n" + "\n".join(perception_summary(rows)))
    return 0 if agree == n and not not_counted else 1


def confusion(matrix: dict[tuple[bool, bool], int], min_share: float, not_counted: list[str]) -> list[str]:
    """The verdicts against the truth as a table (``matrix``: (verdict, truth) → runs) and the
    line README's figure reads, then the runs left out of it (``not_counted``: why each)."""
    true_yes = matrix[(True, True)] + matrix[(False, True)]
    true_no = matrix[(True, False)] + matrix[(False, False)]
    lines = [
        f"Verdict against truth (truth: ≥ {min_share * 100:.0f} % of the spheres really in the bowl; "
        "runs whose setup was taken and that poured):",
        "",
        "| verdict \\ truth | succeeded | failed |",
        "|---|---|---|",
        f"| succeeded | {matrix[(True, True)]} | {matrix[(True, False)]} |",
        f"| failed | {matrix[(False, True)]} | {matrix[(False, False)]} |",
        "",
        f"Confusion: the verdict matched the truth in {matrix[(True, True)] + matrix[(False, False)]} of "
        f"{true_yes + true_no}: {matrix[(True, True)]} of {true_yes} successes, "
        f"{matrix[(False, False)]} of {true_no} failures.",
    ]
    if not_counted:
        lines += ["", f"Not counted ({len(not_counted)}):", *(f"- {why}" for why in not_counted)]
    return lines


def _said(verdict: bool | None) -> str:
    return "—" if verdict is None else ("succeeded" if verdict else "failed")


if __name__ == "__main__":
    sys.exit(main())
