"""Scenario files (services/scenario/model.py): the library parses, and malformed scenarios
are refused with a message naming the problem."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.runtime.human import HumanReport, ReportKind
from services.scenario.model import ScenarioError, library, load_scenario, parse_scenario
from services.scenario.runner import CommandRecord


def test_every_library_scenario_parses_and_says_something() -> None:
    scenarios = library()
    assert {
        "pour",
        "two_commands",
        "urgent_mid_pour",
        "moved_object",
        "impossible",
        "km_restart",
        "tilt_interrupted",
    } <= set(scenarios)
    (fault_a_ta, fault_ag_ex) = scenarios["tilt_interrupted"].steps[1:]
    assert fault_a_ta.after is not None and fault_a_ta.after.delay_s == 0.3
    assert fault_ag_ex.fault is not None and fault_ag_ex.fault.service == "ag_ex"
    for sc in scenarios.values():
        assert sc.commands and sc.description


def test_a_scenario_is_found_by_name_or_path(tmp_path: Path) -> None:
    assert load_scenario("pour").commands[0].say == "pour the jar into the bowl"
    path = tmp_path / "mine.toml"
    path.write_text('name = "x"\n[[steps]]\nsay = "bring the cup to the table"\n')
    assert load_scenario(path).name == "x"
    with pytest.raises(ScenarioError, match=r"no scenario file 'nothing'.*pour"):
        load_scenario("nothing")


def test_a_say_step_comes_from_a_person_unless_it_names_the_gateway() -> None:
    """``from`` (services/scenario/model.py): a person by default; ``two_commands``' second
    command comes from an agent of another FIPA platform through the gateway (R1.4)."""
    first, second = load_scenario("two_commands").commands
    assert (first.from_, second.from_) == ("person", "gateway")
    assert second.say == "pour the jar into the bowl"


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ('name = "x"\nsteps = []', "no steps"),
        ('name = "x"\n[[steps]]\nsay = "a"\nrestart = "a_km"', "exactly one of say, disturb, restart"),
        ('name = "x"\n[[steps]]\nrestart = "a_xx"', "no agent 'a_xx'"),
        ('name = "x"\n[[steps]]\nsay = "a"\nexpect = "great"', "expect must be one of"),
        ('name = "x"\n[[steps]]\nsay = "a"\nafter = { ended = 1 }', "only 0 command"),
        ('name = "x"\n[[steps]]\nsay = "a"\nafter = { step = "s", ended = 1 }', "exactly one of step"),
        ('name = "x"\n[[steps]]\nsay = "a"\ncolour = 3', "colour"),
        ('name = "x"\n[[steps]\n', "not TOML"),
        ('name = "x"\n[[steps]]\ndisturb = { object = "jar" }\nexpect = "failed"', "only a say step"),
        ('name = "x"\n[[steps]]\nsay = "a"\nafter = { delay_s = 1.0 }', "exactly one of step"),
        ('name = "x"\n[[steps]]\nsay = "a"\nafter = { renewed = true, knowledge = true }', "renewed"),
        ('name = "x"\n[[steps]]\nsay = "a"\nafter = { knowledge = true, delay_s = -1 }', "delay_s must be"),
        (
            'name = "x"\n[[steps]]\nsay = "a"\nfrom = "jade"',
            "from must be one of .*, not 'jade'",
        ),
        ('name = "x"\n[[steps]]\nrestart = "a_km"\nfrom = "gateway"', "only a say step comes from someone"),
        (
            'name = "x"\n[[steps]]\nsay = "a"\nfrom = "gateway"\npriority = 2',
            "has no priority",
        ),
    ],
)
def test_malformed_scenarios_are_refused_with_the_reason(text: str, problem: str) -> None:
    with pytest.raises(ScenarioError, match=problem):
        parse_scenario(text, "t.toml")


def test_a_command_is_as_expected_only_with_the_expected_kind_and_text() -> None:
    c = CommandRecord(1, "pour", "r", expect="failed", expect_text="no teapot")
    assert not c.as_expected  # no outcome yet
    c.final = HumanReport(request_id="r", kind=ReportKind.FAILED, text="pour: I know of no teapot")
    assert c.as_expected
    c.final = HumanReport(request_id="r", kind=ReportKind.SUCCEEDED, text="no teapot")
    assert not c.as_expected
