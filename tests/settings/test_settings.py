"""shared/settings.py: how a ``ROCO_*`` variable is read (the module docstring's rule), the
errors a bad value gives, reading only some fields, and the process-wide settings."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from shared.settings import DEFAULT_ROUTER, Settings, env_text, settings


def test_unset_empty_and_blank_values_give_the_defaults() -> None:
    assert Settings.from_env({}) == Settings()
    blank = {Settings.env_name(f): v for f, v in (("seed", ""), ("run_dir", "  "), ("plant", ""))}
    assert Settings.from_env(blank) == Settings()
    assert Settings().router == (DEFAULT_ROUTER,) and Settings().pose_seed is None


def test_values_are_stripped_and_typed() -> None:
    got = Settings.from_env(
        {
            "ROCO_SEED": " 3 ",
            "ROCO_RUN_DIR": " /runs/a ",
            "ROCO_ROUTER": "tcp/a:1, tcp/b:2,",
            "ROCO_CAMERA_IDLE_S": "never",
            "ROCO_RECEIVE_POLL_US": "0",
            "ROCO_LOG_LEVEL": "debug",
            "ROCO_PERCEPTION": "truth",
        }
    )
    assert got.seed == 3 and got.run_dir == Path("/runs/a")
    assert got.router == ("tcp/a:1", "tcp/b:2")
    assert math.isinf(got.camera_idle_s) and got.receive_poll_us == 0.0
    assert got.log_level == "DEBUG" and got.perception == "truth"
    assert Settings.from_env({"ROCO_ROUTER": ","}).router == (DEFAULT_ROUTER,)


@pytest.mark.parametrize(
    ("field", "default"), [("acl", True), ("rerun_camera", True), ("rerun", False), ("tls", True)]
)
def test_a_flag_is_1_or_0_and_anything_else_leaves_its_default(field: str, default: bool) -> None:
    name = Settings.env_name(field)
    assert getattr(Settings.from_env({name: "1"}), field) is True
    assert getattr(Settings.from_env({name: " 0 "}), field) is False
    assert getattr(Settings.from_env({name: "yes"}), field) is default


@pytest.mark.parametrize(
    ("environ", "message"),
    [
        ({"ROCO_SEED": "abc"}, "ROCO_SEED='abc' is not an integer"),
        ({"ROCO_POSE_SEED": "-3"}, "ROCO_POSE_SEED=-3 is negative"),
        ({"ROCO_PERCEPTION": "oracle"}, "ROCO_PERCEPTION='oracle': expected one of camera, truth"),
        ({"ROCO_WORLD": "elsewhere"}, "ROCO_WORLD='elsewhere': expected one of process, loop"),
        ({"ROCO_CAMERA_IDLE_S": "0"}, "ROCO_CAMERA_IDLE_S='0': expected a number of seconds > 0 or 'never'"),
        ({"ROCO_CAMERA_IDLE_S": "inf"}, "ROCO_CAMERA_IDLE_S='inf'"),
        ({"ROCO_RECEIVE_POLL_US": "-1"}, "ROCO_RECEIVE_POLL_US='-1': expected a number of microseconds ≥ 0"),
        ({"ROCO_LOG_LEVEL": "loud"}, "ROCO_LOG_LEVEL='loud': expected one of DEBUG, INFO"),
    ],
)
def test_a_bad_value_is_one_line_naming_the_variable(environ: dict[str, str], message: str) -> None:
    with pytest.raises(ValueError, match="^" + message.replace("(", r"\(").replace(")", r"\)")) as caught:
        Settings.from_env(environ)
    assert "\n" not in str(caught.value)


def test_only_the_fields_asked_for_are_read() -> None:
    bad_seed = {"ROCO_SEED": "abc", "ROCO_RUN_DIR": "/r"}
    assert Settings.from_env(bad_seed, only=("run_dir",)) == Settings(run_dir=Path("/r"))
    assert Settings.from_env(bad_seed, only=()) == Settings()
    with pytest.raises(ValueError, match="ROCO_SEED"):
        Settings.from_env(bad_seed)
    with pytest.raises(KeyError):
        Settings.from_env({}, only=("no_such_field",))


def test_env_name_names_a_field_s_variable() -> None:
    assert Settings.env_name("run_dir") == "ROCO_RUN_DIR"
    assert Settings.env_name("receive_poll_us") == "ROCO_RECEIVE_POLL_US"
    with pytest.raises(KeyError):
        Settings.env_name("rundir")


def test_env_text_writes_a_value_as_the_environment_holds_it() -> None:
    assert [env_text(v) for v in (True, False, None, ("a", "b"), math.inf, 60.0, 2.5, Path("/x"))] == [
        "1",
        "0",
        "",
        "a,b",
        "never",
        "60",
        "2.5",
        "/x",
    ]


def test_from_env_reads_os_environ_now_and_settings_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROCO_SEED", "4")
    assert Settings.from_env().seed == 4
    settings.cache_clear()
    try:
        kept = settings()
        monkeypatch.setenv("ROCO_SEED", "5")
        assert Settings.from_env().seed == 5
        assert settings() is kept and kept.seed == 4
    finally:
        settings.cache_clear()
