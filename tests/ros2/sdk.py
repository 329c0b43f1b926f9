"""zenoh-ros2-sdk (PyPI), an independent ROS 2-over-Zenoh client, fed its message definitions
offline: it reads ``<messages_dir>/<package>/msg/<Name>.msg`` (and ``srv/<Name>.srv``) before it
would git-clone ROS 2's interface repositories (zenoh_ros2_sdk/message_registry.py,
``MessageRegistry.get_msg_file_path``). The .msg texts are written from rosbags' Jazzy type
store (``generate_msgdef``, split at its ``MSG:`` lines), roco_msgs' from
services/ros2/messages.py; a clone is made to fail loudly."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from services.ros2 import messages


def write_definitions(root: Path, types: list[str]) -> None:
    """``root/<pkg>/msg/<Name>.msg`` for each of ``types`` and every type they use, and
    ``root/roco_msgs/srv/Say.srv``."""
    store = messages.typestore()
    for typename in types:
        text, _ = store.generate_msgdef(typename, ros_version=2)
        parts = re.split(r"\n?={80}\nMSG: ", text)
        named = [(typename, parts[0]), *((p.split("\n", 1)[0], p.split("\n", 1)[1]) for p in parts[1:])]
        for name, body in named:
            pkg, *_, short = name.split("/")
            path = root / pkg / "msg" / f"{short}.msg"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body if body.endswith("\n") else body + "\n")
    srv = root / "roco_msgs" / "srv" / "Say.srv"
    srv.parent.mkdir(parents=True, exist_ok=True)
    srv.write_text(messages.SAY_SRV)


def use_offline(root: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Point the SDK's registry at ``root`` and make any git clone raise."""
    from zenoh_ros2_sdk import _cache, message_registry

    def no_clone(repo_name: str, commit: str | None = None) -> str:
        raise RuntimeError(f"zenoh-ros2-sdk tried to clone {repo_name}: a definition is missing offline")

    monkeypatch.setattr(_cache, "clone_to_cache", no_clone)
    monkeypatch.setattr(message_registry, "clone_to_cache", no_clone)
    monkeypatch.setattr(message_registry, "_registry", message_registry.MessageRegistry(str(root)))


def close_session() -> None:
    """Close zenoh-ros2-sdk's process-wide session (it keeps one, ``ZenohSession._instance``),
    so that the next fixture's SDK objects open their own on its router."""
    from zenoh_ros2_sdk.session import ZenohSession

    if ZenohSession._instance is not None:
        ZenohSession._instance.close()
