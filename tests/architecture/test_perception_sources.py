"""No agent and no ag_ex path gives the agents poses from the physics: the camera's
Observation is built from rendered pixels, the head's kinematics and the objects' models;
the physics' truth (velma/executor/ground_truth.py) is read only for tests, the perception log
and tools that judge a run.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GROUND_TRUTH = "velma.executor.ground_truth"
MAY_IMPORT_TRUTH = {
    "velma/executor/runtime.py",  # ROCO_PERCEPTION=truth only (ObservePrimitive)
    "velma/executor/perception_log.py",  # the log beside the camera's estimate
    "velma/executor/camera.py",  # builds the log's truth
    "velma/executor/checkpoint.py",  # observe_scene: judging a run's final world (tools)
    "services/cli/disturb.py",  # the names of the movable objects for `roco disturb`
    "services/bench/scene.py",  # the kitchen the planning benchmark gives a_km (no robot runs)
}
BODY_STATE = {"xpos", "xquat", "xmat", "xipos", "geom_xpos", "geom_xmat", "site_xpos", "site_xmat", "qpos"}
"""MuJoCo state arrays that hold where bodies are (the camera's own pose is ``cam_xpos``)."""


def _sources() -> list[Path]:
    return [p for top in ("velma", "services", "shared") for p in (ROOT / top).rglob("*.py")]


def _imports(tree: ast.AST) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return out


def test_only_named_modules_import_the_ground_truth() -> None:
    offenders = []
    for path in _sources():
        rel = path.relative_to(ROOT).as_posix()
        if rel == "velma/executor/ground_truth.py":
            continue
        if (
            any(
                i == GROUND_TRUTH or i.startswith(GROUND_TRUTH + ".")
                for i in _imports(ast.parse(path.read_text()))
            )
            and rel not in MAY_IMPORT_TRUTH
        ):
            offenders.append(rel)
    assert offenders == []


def test_agents_do_not_reach_the_ground_truth() -> None:
    for path in (ROOT / "services" / "agents").rglob("*.py"):
        text = path.read_text()
        assert "ground_truth" not in text, path
        assert "GroundTruth" not in text, path


def test_camera_path_reads_no_body_state() -> None:
    """The camera's modules never read where the simulation has the bodies, except the
    observer's ``load``, which sets its own MjData to the captured state for rendering."""
    files = [*(ROOT / "velma" / "perception").glob("*.py"), ROOT / "velma" / "executor" / "observer.py"]
    for path in files:
        tree = ast.parse(path.read_text())
        allowed: set[int] = set()
        for fn in ast.walk(tree):
            if isinstance(fn, ast.FunctionDef) and fn.name in ("load", "aim_head"):
                allowed.update(id(n) for n in ast.walk(fn))
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr in BODY_STATE and id(node) not in allowed:
                raise AssertionError(f"{path.relative_to(ROOT)}:{node.lineno} reads .{node.attr}")


def test_only_the_observer_and_the_truth_build_observations() -> None:
    builders = set()
    for path in (ROOT / "velma").rglob("*.py"):
        if "ObjectObservation(" in path.read_text():
            builders.add(path.relative_to(ROOT).as_posix())
    assert builders == {
        "velma/executor/observer.py",
        "velma/executor/ground_truth.py",
        "velma/executor/proprioception.py",
    }


def test_proprioception_reads_only_the_grip_sites() -> None:
    """The grips of an Observation are the hands' frames from the joint angles: the module
    reads the sites' poses and no body's."""
    path = ROOT / "velma" / "executor" / "proprioception.py"
    read = {
        node.attr
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Attribute) and node.attr in BODY_STATE
    }
    assert read == {"site_xpos", "site_xmat"}
