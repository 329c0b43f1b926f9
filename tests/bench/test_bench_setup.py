"""The benchmarks check their own set-up (services/bench/setup_check.py, scene.py,
plan_check.py): the planning benchmark times plan #1 of ``roco run``'s pour, with a_km given
the default kitchen through its C6 fipa-subscribe, and prints no figure when the set-up was
refused or another plan came; the knowledge part queries an a_km that knows the scene."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.bench import parts, scene
from services.bench.messaging import no_access_control
from services.bench.plan_check import expected_plan, leaf_signature, plan1_queries, require_same
from services.bench.scene import kitchen_update
from services.bench.setup_check import SetupRefused, check_counters, check_run_folder, trouble
from services.runtime.counters import CountersReport, save_counters
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate

PLAN_1 = Path(__file__).with_name("plan1_leaves.txt")
"""The leaf signature of plan #1 of a real ``roco run "pour the jar into the bowl"``, taken from
its traffic record (the L_HFSM inform a_pl sent a_co); record it again from a new run when the
planner's plan changes on purpose."""
bench_planning = parts.scripts_module("bench_planning")


def bowl_on_table() -> WorldUpdate:
    """The default kitchen with the bowl said to be on the table: a scene whose plan #1 is
    another plan (face the table, look at the bowl, localise it)."""
    scene = kitchen_update()
    moved = ObjectUpdate(name="bowl", location="table", relation="on")
    return msgspec.structs.replace(scene, objects=(*scene.objects, moved))


def test_plan_1_made_in_process_is_the_one_a_real_run_made() -> None:
    signature = leaf_signature(expected_plan())
    assert list(signature) == PLAN_1.read_text().splitlines()
    assert len(signature) - 1 == 33  # leaves; the last line says the plan is partial


def test_a_plan_for_another_scene_is_not_plan_1() -> None:
    with pytest.raises(SetupRefused, match=r"not plan #1 of the pour: 3 leaves, expected 33; leaf 1: "):
        require_same(expected_plan(bowl_on_table()), expected_plan())


def test_trouble_counters_fail_the_check_and_name_the_agent() -> None:
    fine = {"received.inform": 3, "sent.agree": 1, "rejected": 0}
    check_counters({"a_km": fine}, "setting up")
    bad = {**fine, "rejected": 1, "rejected.protocol_state": 1, "protocol_violations": 1}
    assert trouble(bad) == {"protocol_violations": 1, "rejected": 1, "rejected.protocol_state": 1}
    with pytest.raises(SetupRefused, match=r"^setting up: refused.*a_km: protocol_violations 1, rejected 1"):
        check_counters({"a_pl": fine, "a_km": bad}, "setting up")


def test_a_run_folders_counters_are_checked(tmp_path: Path) -> None:
    with pytest.raises(SetupRefused, match="no agent counters"):
        check_run_folder(tmp_path, "the pour")
    fine = CountersReport("a_co", 0.0, {"received.request": 1, "sent.agree": 1})
    save_counters(tmp_path, {"a_co": fine})
    check_run_folder(tmp_path, "the pour")
    refused = CountersReport("a_pl", 0.0, {"sent.refuse": 1})
    save_counters(tmp_path, {"a_co": fine, "a_pl": refused})
    with pytest.raises(SetupRefused, match=r"^the pour: refused.*: a_pl: sent.refuse 1$"):
        check_run_folder(tmp_path, "the pour")


def _main(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], **planted: object
) -> tuple[int, str, str]:
    monkeypatch.setattr(bench_planning, "measure", functools.partial(bench_planning.measure, **planted))
    monkeypatch.setattr(sys, "argv", ["bench_planning.py", "--runs", "1"])
    code = bench_planning.main()
    out, err = capsys.readouterr()
    return code, out, err


def test_the_planning_bench_refuses_the_inform_sent_before_the_subscription_is_agreed(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _main(monkeypatch, capsys, agree_first=False)
    assert code == 1 and out == ""
    assert len(err.splitlines()) == 1
    assert err.startswith("roco: bench_planning: giving a_km the scene: refused, not understood")
    assert "a_km: " in err and "rejected.protocol_state 1" in err


def test_the_planning_bench_refuses_to_time_another_plan(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _main(monkeypatch, capsys, update=bowl_on_table())
    assert code == 1 and out == ""
    assert err.startswith(
        "roco: bench_planning: the timed plan is not plan #1 of the pour: 3 leaves, expected 33"
    )


def test_the_planning_bench_times_plan_1() -> None:
    with no_access_control():
        rows = bench_planning.measure(1)
    assert [(queries, leaves) for _, _, queries, leaves in rows] == [(15, 33)]


def test_the_knowledge_part_refuses_an_a_km_that_does_not_know_the_scene(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    real = scene.SceneSource

    class EmptyScene(real):  # type: ignore[misc, valid-type]
        """Gives the a_km process an empty scene (the in-process plan still has the kitchen)."""

        def __init__(self, session: Any, _update: WorldUpdate) -> None:
            super().__init__(session, WorldUpdate(stamp=0.0, objects=()))

    monkeypatch.setattr(scene, "SceneSource", EmptyScene)
    with pytest.raises(SetupRefused, match=r"a_km does not know the scene after it was given: jar \("):
        parts.knowledge(True)


def test_roco_bench_prints_one_line_and_no_figure_for_a_refused_set_up(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from typer.testing import CliRunner

    from services.cli.bench import bench_app

    def refused(quick: bool) -> object:
        raise SetupRefused(
            "giving a_km the scene: refused, not understood or against the protocol: a_km: rejected 1"
        )

    monkeypatch.setattr(parts, "planning", refused)
    out = tmp_path / "b.md"
    got = CliRunner().invoke(bench_app, ["--only", "planning", "--quick", "--out", str(out)])
    assert got.exit_code == 1
    said = [line for line in got.output.splitlines() if line.startswith("roco: ")]
    assert said == [
        "roco: bench: planning: giving a_km the scene: refused, not understood or against the protocol: "
        "a_km: rejected 1"
    ]
    assert "Traceback" not in got.output
    assert "| plan #1, request" not in out.read_text()


def test_the_timed_query_set_is_as_long_as_plan_1s() -> None:
    # what the knowledge part times as "plan #1 query set": as many queries as a_pl counts
    assert len(plan1_queries()) == expected_plan().km_queries
