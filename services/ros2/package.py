"""roco's ROS 2 interfaces as a ROS 2 package a colcon workspace builds: ``roco_msgs`` with
``package.xml`` (format 3, REP 149), ``CMakeLists.txt`` (rosidl_generate_interfaces) and the
``.msg``/``.srv`` files of services/ros2/messages.py, so that ``ros2 topic echo``, ``ros2 service
call`` and ``ros2 bag`` read roco's own types. Nothing here needs the ``ros2`` extra.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

from services.ros2.messages import MESSAGES, PACKAGE, SAY, SAY_SRV

DEPENDENCIES = ("builtin_interfaces",)
"""The interface packages roco_msgs' types use (``builtin_interfaces/Time``)."""


def interface_files() -> dict[str, str]:
    """Each interface file of the package, by its path in it (``msg/Communicate.msg``,
    ``srv/Say.srv``) → its text."""
    files = {f"msg/{name.rsplit('/', 1)[1]}.msg": text for name, text in MESSAGES.items()}
    files[f"srv/{SAY.rsplit('/', 1)[1]}.srv"] = SAY_SRV
    return files


def _version() -> str:
    try:
        return metadata.version("roco")
    except metadata.PackageNotFoundError:
        return "0.0.0"


def package_xml() -> str:
    """``package.xml`` (format 3) of an interface package built by ament_cmake and rosidl."""
    depends = "\n".join(f"  <depend>{d}</depend>" for d in DEPENDENCIES)
    return f"""<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" schematypens="http://www.w3.org/2001/XMLSchema"?>
<package format="3">
  <name>{PACKAGE}</name>
  <version>{_version()}</version>
  <description>roco's ROS 2 interfaces: FIPA ACL traffic, task state, a sentence service</description>
  <maintainer email="roco@localhost">roco</maintainer>
  <license>Apache-2.0</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
{depends}
  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"""


def cmake_lists() -> str:
    """``CMakeLists.txt`` generating every interface file of :func:`interface_files`."""
    files = "\n".join(f'  "{path}"' for path in interface_files())
    finds = "\n".join(f"find_package({d} REQUIRED)" for d in DEPENDENCIES)
    return f"""cmake_minimum_required(VERSION 3.8)
project({PACKAGE})
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
{finds}
rosidl_generate_interfaces(${{PROJECT_NAME}}
{files}
  DEPENDENCIES {" ".join(DEPENDENCIES)}
)
ament_export_dependencies(rosidl_default_runtime)
ament_package()
"""


def write_package(out: Path) -> list[Path]:
    """Write the package ``roco_msgs`` into ``out`` (made; it must not exist or be an empty
    folder) and return the files written. Raises FileExistsError when ``out`` holds anything,
    OSError when it cannot write."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"{out} exists and is not an empty folder")
    texts = {"package.xml": package_xml(), "CMakeLists.txt": cmake_lists(), **interface_files()}
    written = []
    for rel, text in texts.items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, "utf-8")
        written.append(path)
    return written
