"""``roco spec check`` and ``show`` (services/spec/check.py, show.py): the shipped
specification passes; deliberately broken variants of it fail with a precise message."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.spec.check import check_report
from services.spec.decomposition import load_decomposition, replay
from services.spec.model import DEFAULT_SPEC, default_spec
from services.spec.show import graph_dot, graph_svg, steps_markdown

SHIPPED = DEFAULT_SPEC.read_text()
KM_GROUP = next(a.group for a in default_spec().agents if a.name == "a_km")
"""The group a_km substitutes in the shipped specification (``km``, until a step splits it)."""

# (name, text replaced, replacement, expected message)
BROKEN = [
    (
        "channel left at a split group",
        'reallocated = [{ number = 3, from = "cp", to = "pl" }]',
        "reallocated = []",
        "step 4: channel C3 ends at 'cp', which this step splits into pl and km; reallocate it",
    ),
    (
        "channel to a group that no longer exists",
        'new_channels = [{ number = 4, ends = ["pl", "km"]',
        'new_channels = [{ number = 4, ends = ["pl", "cp"]',
        "step 4: new channel C4 ends at 'cp', which is not in the fringe (hi, co, pl, km, ec)",
    ),
    (
        "a split of a group that was already split",
        'split = "cp"',
        'split = "da"',
        "step 4: splits group 'da', which is not in the fringe (hi, co, cp, ec)",
    ),
    (
        "a requirement no step addresses",
        'requirements = ["R3.2"]',
        "requirements = []",
        "stop condition: requirement R3.2 is addressed by no step",
    ),
    (
        "channels numbered out of order",
        '{ number = 6, ends = ["ta", "km"]',
        '{ number = 7, ends = ["ta", "km"]',
        "step 5: new channel C7 should be numbered C6",
    ),
    (
        "an agent for a group the decomposition never made",
        'group = "pl"',
        'group = "planner"',
        "stop condition: group 'pl' of the final fringe is substituted by no agent",
    ),
    (
        "a channel between other agents than the decomposition says",
        'ends = ["ag_ex", "a_ta"]',
        'ends = ["a_co", "a_ta"]',
        "channel C5 joins a_ta and ag_ex by the decomposition, but a_co and a_ta in [[channels]]",
    ),
    (
        "a performative without a language",
        'languages = { request = "L_HFSM", agree = "L_HFSM"',
        'languages = { agree = "L_HFSM"',
        "C3 fipa-request: request may be sent but has no language",
    ),
    (
        "a content schema that is no term of the language",
        'contents = { request = ["GroundTaskNetwork"], inform = ["HierarchicalPlan"]',
        'contents = { request = ["GroundTaskNetwork"], inform = ["WorldUpdate"]',
        "C3 fipa-request: inform may carry WorldUpdate, which is no term of L_HFSM",
    ),
    (
        "a size estimate that is no interval",
        "sizes = { request = [100, 1000], inform = [500, 100000]",
        "sizes = { request = [1000, 100], inform = [500, 100000]",
        "C3 fipa-request: the size estimate of request must be 0 < min ≤ max, not [1000, 100]",
    ),
    (
        "a property step on a channel that does not serve the requirement",
        '{ name = "sub", channel = "C6", protocol = "fipa-subscribe"',
        '{ name = "sub", channel = "C5", protocol = "fipa-subscribe"',
        "requirement R3.2, property 1 (a_ta agrees to a_km's subscription and informs it of the world "
        "in it), step 1 (C5 fipa-subscribe subscribe Subscription a_km→*): C5 does not serve it "
        "(its steps: 6; their channels: C6)",
    ),
    (
        "a property step with a content term the channel does not list",
        'performative = "query-ref", content = "SparqlQuery" }',
        'performative = "query-ref", content = "ObjectQuery" }',
        "requirement R1.3, property 1 (a_km answers a_hi's query for the names of things), "
        "step 1 (C7 fipa-query query-ref ObjectQuery): C7 lists no content ObjectQuery for it "
        "(listed: SparqlQuery)",
    ),
    (
        "a property step with a performative no role of the protocol sends",
        '{ channel = "C2", protocol = "fipa-request", performative = "agree", answers = "cmd" }',
        '{ channel = "C2", protocol = "fipa-request", performative = "confirm", answers = "cmd" }',
        "requirement R1.1, property 1 (a_co agrees to a person's interpreted command, in reply to it), "
        "step 2 (C2 fipa-request confirm): no role of fipa-request on C2 sends confirm",
    ),
    (
        "a property step that names no earlier step",
        '{ channel = "C2", protocol = "fipa-request", performative = "agree", answers = "cmd" }',
        '{ channel = "C2", protocol = "fipa-request", performative = "agree", answers = "command" }',
        "requirement R1.1, property 1 (a_co agrees to a person's interpreted command, in reply to it): "
        "step 2 (C2 fipa-request agree): names command, which no earlier step is",
    ),
    (
        "a requirement under a parent that does not exist",
        'parent = "R3"\ntext = "update the environment model"',
        'parent = "R9"\ntext = "update the environment model"',
        "requirement R3.2: its parent R9 does not exist",
    ),
    (
        "a channel to a group outside the system that no step declares",
        'outside = { xp = "an agent of another FIPA platform that asks the robot as a person would" }\n',
        "",
        "step 8: new channel C8 ends at 'xp', which is not in the fringe",
    ),
    (
        "a group outside the system substituted by no external role",
        'name = "x_fipa"\ngroup = "xp"',
        'name = "x_fipa"\ngroup = "xq"',
        "group 'xp' outside the system is substituted by no external role",
    ),
    (
        "an agent substituting a group outside the system",
        f'knowledge.agent:KnowledgeManager"\ngroup = "{KM_GROUP}"',
        'knowledge.agent:KnowledgeManager"\ngroup = "xp"',
        "group 'xp' outside the system is substituted by agent a_km",
    ),
]


def test_the_shipped_specification_is_sound() -> None:
    ok, text = check_report(DEFAULT_SPEC)
    assert ok, text
    assert "OK: the decomposition is sound" in text


@pytest.mark.parametrize(("name", "old", "new", "message"), BROKEN, ids=[b[0] for b in BROKEN])
def test_a_broken_variant_fails_with_a_precise_message(
    tmp_path: Path, name: str, old: str, new: str, message: str
) -> None:
    assert SHIPPED.count(old) == 1, f"fixture {name!r} no longer matches the shipped spec"
    path = tmp_path / "broken.toml"
    path.write_text(SHIPPED.replace(old, new))
    ok, text = check_report(path)
    assert not ok
    assert message in text, text


def test_a_file_that_is_not_a_specification_is_one_clear_problem(tmp_path: Path) -> None:
    path = tmp_path / "x.toml"
    path.write_text('system = "RoCo"\n[[steps]]\nnumber = "one"\n')
    ok, text = check_report(path)
    assert not ok and str(path) in text and text.count("\n") == 0


def test_replay_reaches_the_papers_six_groups_and_channels() -> None:
    """The paper's six groups and channels (Figure 6), C7 between hi and km and C8
    between hi and xp, a group outside the system: the fringe after step 8 (a step added
    since may split these further)."""
    final = next(s for s in replay(load_decomposition()) if s.step.number == 8)
    assert sorted(final.fringe) == ["co", "ex", "hi", "km", "pl", "ta"]  # paper Figure 6
    ends = {c.name: set(c.ends) for c in final.channels.values()}
    assert ends == {
        "C1": {"co", "ta"},
        "C2": {"co", "hi"},
        "C3": {"co", "pl"},
        "C4": {"pl", "km"},
        "C5": {"ex", "ta"},
        "C6": {"ta", "km"},
        "C7": {"hi", "km"},
        "C8": {"hi", "xp"},
    }
    assert final.channels[6].transmits == ["knowledge needed by a_ta", "updates of the environment model"]


def test_show_renders_every_step_and_the_graph() -> None:
    from services.spec.model import load

    decomposition = load_decomposition()
    text = steps_markdown(decomposition)
    assert "g_xp outside the system" in text
    assert text.count("## Step ") == len(decomposition.steps) >= 8
    assert "g_cp := ⟨g_pl, g_km⟩" in text and "C3: cp ↦ pl" in text
    spec = load()
    svg = graph_svg(spec)
    assert svg.startswith("<svg") and all(f">{a.name}<" in svg for a in spec.agents)
    assert ">x_fipa<" in svg and 'stroke-dasharray="4 3"' in svg
    assert graph_dot(spec).count(" -- ") == len(spec.channels)


def test_roco_spec_check_exits_1_on_a_broken_spec(tmp_path: Path) -> None:
    _name, old, new, message = BROKEN[0]
    path = tmp_path / "broken.toml"
    path.write_text(SHIPPED.replace(old, new))
    bad = subprocess.run(
        [sys.executable, "-m", "services.cli", "spec", "check", "--spec", str(path)],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 1 and message in bad.stdout
    good = subprocess.run(
        [sys.executable, "-m", "services.cli", "spec", "check"], capture_output=True, text=True
    )
    assert good.returncode == 0, good.stdout + good.stderr


def test_verify_code_passes_on_the_shipped_agents() -> None:
    from services.spec_check.code_check import verify_code_report

    ok, text = verify_code_report(DEFAULT_SPEC)
    assert ok, text
    files = len(list((Path(__file__).resolve().parents[2] / "services" / "agents" / "executor").glob("*.py")))
    assert f"ag_ex: {files} files; 2 protocol roles agree with the specification:" in text
    assert (
        "  C5 fipa-request participant with a_ta in L_EX, L_SD: receives cancel, request; "
        "sends agree, failure, inform, refuse"
    ) in text
    assert (
        "  C4 fipa-query participant with a_pl in L_WM (declared for every channel): receives cancel, "
        "query-if, query-ref"
    ) in text
    # a_km plays a role per protocol of each channel it ends
    km_roles = sum(len(c.protocols) for c in default_spec().channels if "a_km" in c.ends)
    assert f"a_km: 6 files; {km_roles} protocol roles agree with the specification:" in text


def test_verify_code_reports_an_implementation_that_does_not_exist(tmp_path: Path) -> None:
    from services.spec_check.code_check import verify_code_report

    path = tmp_path / "spec.toml"
    path.write_text(
        SHIPPED.replace("services.agents.planner.agent:Planner", "services.nowhere.agent:Planner")
    )
    ok, text = verify_code_report(path)
    assert not ok and "no module 'services.nowhere.agent'" in text


def test_a_misspelt_field_anywhere_in_the_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "typo.toml"
    path.write_text(
        SHIPPED.replace(
            '  languages = { request = "L_HFSM", inform = "L_SW"',
            '  langauges = { request = "L_HFSM", inform = "L_SW"',
        )
    )
    ok, text = check_report(path)
    assert not ok and "unknown field `langauges` - at `$.channels[0].protocols[0]`" in text


def test_roco_spec_deadlock_and_verify_exit_codes(tmp_path: Path) -> None:
    fixtures = Path(__file__).resolve().parents[1] / "spec" / "fixtures"

    def roco(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "services.cli", "spec", *args], capture_output=True, text=True
        )

    shipped = roco("deadlock")
    assert shipped.returncode == 0 and "no deadlock found" in shipped.stdout
    broken = roco("deadlock", "--spec", str(fixtures / "deadlock_protocol.toml"))
    assert broken.returncode == 1 and "deadlock" in broken.stdout.lower()
    library = roco("deadlock", "--library")
    assert library.returncode == 0 and "fipa-dutch-auction (FIPA SC00032)" in library.stdout
    assert library.stdout.rstrip().splitlines()[-1].startswith("no deadlock found (")
    both = roco("deadlock", "--library", "--spec", str(fixtures / "deadlock_protocol.toml"))
    assert both.returncode == 2 and both.stderr.startswith("roco: --library explores the built-in")
    missing = roco("verify", str(tmp_path / "no-run"))
    last = missing.stderr.splitlines()[-1]
    assert missing.returncode == 2 and last.startswith("roco: ") and last.endswith("no such run folder")


def test_a_foreign_agent_plays_the_external_role_and_roco_agents_themselves() -> None:
    """every local@platform name that is not one of roco's agents plays x_fipa."""
    from services.spec.model import is_foreign

    spec = default_spec()
    assert spec.role_of("da0@host:1099/JADE") == "x_fipa"
    assert spec.role_of("a_hi") == "a_hi" and spec.role_of("nobody") == "nobody"
    assert is_foreign("a@b") and not is_foreign("@b") and not is_foreign("a@") and not is_foreign("a_co")


def test_two_external_roles_or_one_with_an_agents_name_do_not_load(tmp_path: Path) -> None:
    from services.spec.model import SpecError, load

    for old, new, message in (
        (
            "\n[[channels]]\n",
            '\n[[externals]]\nname = "x_two"\ngroup = "xq"\n\n[[channels]]\n',
            "at most one",
        ),
        ('name = "x_fipa"', 'name = "a_co"', "must be no agent's name and no GUID"),
    ):
        path = tmp_path / "spec.toml"
        path.write_text(SHIPPED.replace(old, new, 1))
        with pytest.raises(SpecError, match=message):
            load(path)
