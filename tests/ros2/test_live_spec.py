"""The external role of ROS 2 callers in the specification (services/spec/model.py): the names
``…@ros2`` play x_ros2 and reach a_hi on C9 only; every other foreign name plays x_fipa (C8);
the roles' platforms are checked when the file loads."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.spec.model import DEFAULT_SPEC, SpecError, channel_between, default_spec, load

CALLER = "c000102030405060708090a0b0c0d0e0f@ros2"
JADE = "da0@host:1099/JADE"


def test_ros2_callers_play_x_ros2_on_c9_and_foreign_agents_x_fipa_on_c8() -> None:
    spec = default_spec()
    assert spec.role_of(CALLER) == "x_ros2" and spec.role_of(JADE) == "x_fipa"
    assert spec.role_of("x@ros2.example") == "x_fipa"  # another platform's name
    assert spec.role_of("a_hi") == "a_hi"
    c9, c8 = channel_between(spec, "x_ros2", "a_hi"), channel_between(spec, "x_fipa", "a_hi")
    assert c9 is not None and c9.name == "C9" and c8 is not None and c8.name == "C8"
    assert channel_between(spec, "x_ros2", "a_co") is None


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        ('platform = "ros2"\n', "at most one external role per platform"),  # two without one
        ('platform = "ros 2"\n', "is no word"),
        ('name = "x_ros2"\n', None),
    ],
)
def test_the_platforms_of_external_roles_are_checked(tmp_path: Path, edit: str, says: str | None) -> None:
    text = DEFAULT_SPEC.read_text()
    if says is None:  # two roles of one name
        text = text.replace('name = "x_fipa"\n', 'name = "x_ros2"\n')
        says = "named twice"
    else:
        text = text.replace('platform = "ros2"\n', "" if edit.endswith('"ros2"\n') else edit)
    path = tmp_path / "spec.toml"
    path.write_text(text)
    with pytest.raises(SpecError, match=says):
        load(path)
