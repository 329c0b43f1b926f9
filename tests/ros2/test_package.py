"""The ROS 2 package roco_msgs that `roco ros2 --write-package` writes (services/ros2/package.py):
its interface files are the definitions roco puts on the wire (the same RIHS01 hashes), its
CMakeLists.txt generates every one of them, its package.xml is an interface package."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from services.ros2.package import write_package

rosbags = pytest.importorskip("rosbags", reason="the ros2 extra (pip install -e '.[ros2]': rosbags)")

from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

from services.ros2 import messages, rmw  # noqa: E402


def _fresh_hashes(root: Path) -> dict[str, str]:
    """The RIHS01 hash of each interface file under ``root``, from a store that holds only
    ROS 2 Jazzy's types and what the files say."""
    store = get_typestore(Stores.ROS2_JAZZY)
    hashes = {}
    for path in sorted((root / "msg").glob("*.msg")):
        name = f"roco_msgs/msg/{path.stem}"
        store.register(get_types_from_msg(path.read_text("utf-8"), name))
        hashes[name] = rmw.type_hash(store, name)
    for path in sorted((root / "srv").glob("*.srv")):
        name = f"roco_msgs/srv/{path.stem}"
        request, response = path.read_text("utf-8").split("\n---\n")
        rmw.register_service(store, name, request, response)
        hashes[name] = rmw.type_hash(store, name)
    return hashes


def test_the_package_holds_the_definitions_roco_puts_on_the_wire(tmp_path: Path) -> None:
    write_package(tmp_path / "roco_msgs")
    hashes = _fresh_hashes(tmp_path / "roco_msgs")
    store = messages.typestore()
    assert set(hashes) == {*messages.MESSAGES, messages.SAY}
    for name in messages.MESSAGES:
        assert hashes[name] == rmw.type_hash(store, name), name
    wire = get_typestore(Stores.ROS2_JAZZY)
    rmw.register_service(wire, messages.SAY, messages.SAY_REQUEST_MSG, messages.SAY_RESPONSE_MSG)
    assert hashes[messages.SAY] == rmw.type_hash(wire, messages.SAY)


def test_cmake_generates_every_interface_file_and_package_xml_is_an_interface_package(tmp_path: Path) -> None:
    root = tmp_path / "roco_msgs"
    write_package(root)
    on_disk = {p.relative_to(root).as_posix() for p in root.rglob("*.*") if p.suffix in (".msg", ".srv")}
    listed = set(re.findall(r'"((?:msg|srv)/\w+\.(?:msg|srv))"', (root / "CMakeLists.txt").read_text()))
    assert listed == on_disk and len(on_disk) == len(messages.MESSAGES) + 1
    xml = ET.parse(root / "package.xml").getroot()
    assert xml.get("format") == "3" and xml.findtext("name") == "roco_msgs"
    assert xml.findtext("member_of_group") == "rosidl_interface_packages"
    assert {d.text for d in xml.findall("depend")} == {"builtin_interfaces"}


def test_a_folder_that_holds_something_is_not_written_into(tmp_path: Path) -> None:
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(FileExistsError):
        write_package(tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_roco_ros2_writes_the_package_and_refuses_a_full_folder_in_one_line(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from services import cli

    out = tmp_path / "ws" / "src" / "roco_msgs"
    first = CliRunner().invoke(cli.app, ["ros2", "--write-package", str(out)], prog_name="roco")
    assert first.exit_code == 0 and (out / "srv" / "Say.srv").is_file(), first.output
    again = CliRunner().invoke(cli.app, ["ros2", "--write-package", str(out)], prog_name="roco")
    assert again.exception is None or isinstance(again.exception, SystemExit), again.exception
    assert again.exit_code == 1 and again.output.startswith("roco: "), again.output
    assert again.output.count("\n") == 1, again.output
