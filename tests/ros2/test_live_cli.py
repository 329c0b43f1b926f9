"""``roco ros2``'s options and ``--ros2`` on ``roco run``, ``roco scenario`` and ``roco up``
(services/cli/ros2.py, run.py, up.py; services/control/start.py): what is
published is only what is asked; a bad namespace is one ``roco:`` line. No fleet starts."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services import cli
from services.fleet.launcher import Fleet
from services.ros2.face import CAMERA, JOINT_STATES, TASK_STATE, TF, FaceConfig
from services.ros2.live import LiveConfig, LiveError, serve
from tests.support.router import router_fleet


def invoke(args: list[str]) -> tuple[int, str]:
    result = CliRunner().invoke(cli.app, args, prog_name="roco")
    return result.exit_code, result.output


@pytest.mark.parametrize(
    ("args", "topics", "say"),
    [
        ([], set(), True),
        (["--joint-states"], {JOINT_STATES}, True),
        (["--tf", "--task-state", "--no-say"], {TF, TASK_STATE}, False),
        (["--camera"], {CAMERA}, True),
        (["--all"], {JOINT_STATES, TF, TASK_STATE, CAMERA}, True),
    ],
)
def test_only_the_topics_asked_for_are_published(
    args: list[str], topics: set[str], say: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    given: list[LiveConfig] = []
    monkeypatch.setattr("services.ros2.live.main", lambda config: given.append(config) or 0)
    code, out = invoke(["ros2", *args, "--router", "tcp/127.0.0.1:1", "--domain", "7", "--namespace", "/k"])
    assert code == 0, out
    (config,) = given
    assert (set(config.face.topics), config.face.say) == (topics, say)
    assert (config.face.domain, config.face.namespace, config.endpoint) == (7, "/k", "tcp/127.0.0.1:1")


def test_run_and_scenario_pass_ros2_to_the_runner(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    given: list[dict[str, object]] = []
    monkeypatch.setattr("services.cli.run.run_scenario", lambda sc, runs_dir, **kw: given.append(kw))
    kitchen = ["--ros2", "--ros2-domain", "3", "--ros2-namespace", "/kitchen"]
    for args in ([], ["--ros2"], kitchen, kitchen[1:]):
        code, out = invoke(["run", "pour the jar into the bowl", *args, "--runs-dir", str(tmp_path)])
        assert code == 0, out
    assert [g["ros2"] for g in given] == [
        None,
        ("--all", "--domain", "0", "--namespace", "/"),
        ("--all", "--domain", "3", "--namespace", "/kitchen"),
        None,  # no face without --ros2
    ]
    code, out = invoke(
        ["run", "pour", "--ros2", "--ros2-namespace", "/bad name", "--runs-dir", str(tmp_path)]
    )
    assert code == 2 and "roco: --ros2-namespace: name '/bad name' is no ROS 2" in out and len(given) == 4
    for command in (["up"], ["scenario"]):
        help_text = invoke([*command, "--help"])[1]
        assert "--ros2" in help_text and "--ros2-domain" in help_text and "--ros2-namespace" in help_text


def test_up_starts_the_face_with_its_domain_and_namespace() -> None:
    from services.control.start import start_faces

    class Started:
        def __init__(self) -> None:
            self.args: list[tuple[str, ...]] = []

        def start_ros2(self, args: tuple[str, ...]) -> None:
            self.args.append(args)

        def wait_alive(self, session: object, names: list[str], timeout: float) -> float:
            return 0.0

    fleet = Started()
    face = ("--all", "--domain", "3", "--namespace", "/kitchen")
    line = start_faces(fleet, None, None, face)  # type: ignore[arg-type]
    assert fleet.args == [face] and "roco ros2 --all --domain 3 --namespace /kitchen" in line
    assert start_faces(fleet, None, None, None) == "" and fleet.args == [face]  # type: ignore[arg-type]


@pytest.fixture
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    yield from router_fleet(tmp_path_factory, "ros2_cli")


def test_a_bad_domain_or_namespace_is_refused_in_one_line(router: Fleet) -> None:
    code, out = invoke(["ros2", "--domain", "300", "--router", router.endpoint])
    assert code == 2 and "--domain" in out  # typer's own range check: 0 to 232
    with pytest.raises(LiveError, match="'/bad name' is no ROS 2 topic or service name"):
        serve(LiveConfig(router.endpoint, FaceConfig(namespace="/bad name")), threading.Event())


@pytest.mark.parametrize(
    "args",
    [["ros2", "--all"], ["run", "pour the jar into the bowl", "--ros2"], ["up", "--ros2"]],
)
def test_without_the_ros2_extra_the_face_is_one_line_and_nothing_starts(
    args: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "rosbags" else real(name, *a)
    )
    started: list[str] = []
    monkeypatch.setattr(Fleet, "start_router", lambda self, *a, **k: started.append("router"))
    monkeypatch.setattr("services.ros2.live.main", lambda config: started.append("face") or 0)
    code, out = invoke(args)
    assert code == 2 and started == [], (code, out, started)
    assert out.startswith("roco: ROS 2 needs the ros2 extra: pip install -e '.[ros2]'"), out
    assert out.count("\n") == 1, out
