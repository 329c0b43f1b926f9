"""``roco doctor``'s one line on the ros2 extra that ``roco export --mcap`` needs."""

from __future__ import annotations

import pytest
from packaging.requirements import Requirement

from services.doctor import environment
from services.doctor.model import Use


def test_installed_extra_is_found_with_its_versions() -> None:
    pytest.importorskip("rosbags", reason="the ros2 extra's rosbags is not installed")
    check = environment.ros2_extra_check()
    assert check.found and check.use is Use.EXPORT and not check.how
    assert [part.split()[0] for part in check.detail.split(", ")] == ["rosbags", "mcap", "mcap-ros2-support"]


def test_missing_library_names_it_and_how(monkeypatch: pytest.MonkeyPatch) -> None:
    wanted = [Requirement("rosbags>=0.11"), Requirement("no-such-roco-library>=1")]
    monkeypatch.setattr(environment, "extra_requirements", lambda extra: wanted)
    check = environment.ros2_extra_check()
    assert not check.found and "no-such-roco-library" in check.detail and "rosbags" not in check.detail
    assert check.how == environment.ROS2_HOW
    assert check in environment.checks()
