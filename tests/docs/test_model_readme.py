"""velma/model/README.md, the robot's facts in prose, against the model that uses them
(velma/model/robot_mjcf.py): the KUKA LWR4+ table, the BarrettHand table, the arm mounts and the
masses say what the generator writes into velma.xml; its links reach their headings. A number
changed in a copy of the README is caught."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from tests.docs import doccheck
from velma.model import robot_mjcf as robot

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "velma" / "model" / "README.md"
AXES = {"z": (0, 0, 1), "y": (0, 1, 0), "−y": (0, -1, 0), "+z": (0, 0, 1), "−z": (0, 0, -1)}
"""An axis as the README writes it → the unit vector."""
NUMBER = r"−?\d+(?:\.\d+)?"


def _num(text: str) -> float:
    """A README number (``−`` is the minus sign, ``π`` and ``π/2`` are read)."""
    text = text.strip().replace("−", "-")
    if "π" in text:
        sign = -1.0 if text.startswith("-") else 1.0
        head, _, tail = text.lstrip("-").partition("/")
        factor = float(head.replace("π", "") or 1.0)
        return sign * factor * math.pi / (float(tail) if tail else 1.0)
    return float(text)


def _section(text: str, heading: str) -> str:
    """The text under the ``## heading`` of ``text``, up to the next ``## ``; KeyError if absent."""
    match = re.search(rf"^## {re.escape(heading)}\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    if match is None:
        raise KeyError(heading)
    return match.group(1)


def _rows(section: str) -> list[list[str]]:
    """The body rows of the Markdown tables in ``section``, as stripped cells."""
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in section.splitlines()]
    return [r for r in rows if len(r) > 2 and not set(r[0]) <= set("-: ") and r[0] not in ("joint",)]


def mismatches(text: str) -> list[str]:
    """What the README ``text`` says that velma/model/robot_mjcf.py does not use, one line each."""
    out: list[str] = []

    arm = _rows(_section(text, "KUKA LWR4+ arms"))
    if len(arm) != len(robot.ARM_JOINTS):
        out.append(f"LWR4+ table: {len(arm)} rows, the model has {len(robot.ARM_JOINTS)} joints")
    for row, (dz, axis, limit, velocity, torque) in zip(arm, robot.ARM_JOINTS, strict=False):
        joint = (_num(row[1]), AXES.get(row[2]), _num(row[3].lstrip("±")), _num(row[4]), _num(row[5]))
        if joint != (dz, tuple(axis), limit, velocity, torque):
            out.append(f"LWR4+ joint {row[0]}: README {joint}, model {(dz, axis, limit, velocity, torque)}")

    hand = {r[0]: r for r in _rows(_section(text, "BarrettHand BH8-282"))}
    ranges = {
        "finger 1 spread": robot.FINGER_SPREAD_RANGE,
        "finger 2 spread": robot.FINGER_SPREAD_RANGE,
        "fingers 1, 2 proximal": robot.PROXIMAL_RANGE,
        "finger 3 proximal": robot.PROXIMAL_RANGE,
        "distal (each finger)": robot.DISTAL_RANGE,
    }
    for name, (lo, hi) in ranges.items():
        cells = hand.get(name)
        span = tuple(_num(x) for x in cells[3].split("…")) if cells else None
        if span is None or not all(
            math.isclose(a, b, abs_tol=1e-9) for a, b in zip(span, (lo, hi), strict=True)
        ):
            out.append(f"BarrettHand {name}: README range {span}, model {(lo, hi)}")
    origins = {
        "finger 1 spread": (robot.SPREAD_ORIGIN_X, 0.0, robot.SPREAD_ORIGIN_Z),
        "finger 2 spread": (-robot.SPREAD_ORIGIN_X, 0.0, robot.SPREAD_ORIGIN_Z),
        "fingers 1, 2 proximal": robot.PROXIMAL_IN_KNUCKLE,
        "finger 3 proximal": robot.F3_PROXIMAL_IN_PALM[0],
        "distal (each finger)": (robot.DISTAL_IN_PROXIMAL_X, 0.0, 0.0),
    }
    for name, xyz in origins.items():
        found = re.search(rf"\(({NUMBER}), ({NUMBER}), ({NUMBER})\)", hand[name][1]) if name in hand else None
        origin = tuple(_num(x) for x in found.groups()) if found else None
        if origin != tuple(xyz):
            out.append(f"BarrettHand {name}: README origin {origin}, model {xyz}")

    structure = _section(text, "Structure")
    for side, (xyz, rpy) in robot.ARM_MOUNT.items():
        found = re.search(rf"{side} \(([^;]*); ([^)]*)\)", structure)
        mount = tuple(tuple(_num(x) for x in part.split(",")) for part in found.groups()) if found else None
        if mount != (xyz, rpy):
            out.append(f"arm mount {side}: README {mount}, model {(xyz, rpy)}")
    for value, pattern in (
        (robot.TORSO_JOINT_Z, rf"`torso_0_joint` turns `torso_link0` about z,\s+({NUMBER}) above"),
        (robot.TORSO_LIMIT, rf"limits ±({NUMBER}), velocity 30 °/s"),
        (robot.TORSO_VELOCITY, rf"30 °/s \(({NUMBER}) rad/s\)"),
        (robot.TORSO_DAMPING, rf"damping ({NUMBER})\s+N·m·s/rad"),
        (robot.TORSO_BASE_MASS, rf"weigh ({NUMBER}) kg each"),
        (robot.NECK_VELOCITY, rf"at most ({NUMBER}) rad/s"),
    ):
        found = re.search(pattern, structure)
        if found is None or _num(found.group(1)) != value:
            out.append(f"Structure: /{pattern}/ says {found and found.group(1)}, model {value}")
    head = re.search(
        rf"`head_base` sits on `torso_link0` at \(({NUMBER}), ({NUMBER}), ({NUMBER})\)", structure
    )
    if head is None or tuple(_num(x) for x in head.groups()) != robot.HEAD_BASE:
        out.append(f"Structure: head_base at {head and head.groups()}, model {robot.HEAD_BASE}")

    masses = re.search(
        rf"Palm ({NUMBER}) kg, knuckle-one ({NUMBER}) kg, proximal ({NUMBER}) kg, distal ({NUMBER}) kg",
        _section(text, "BarrettHand BH8-282"),
    )
    model = (
        robot.PALM_MASS,
        robot.KNUCKLE_ONE_MASS,
        robot.PROXIMAL_MASS,
        robot.DISTAL_MASS,
    )
    if masses is None or tuple(_num(x) for x in masses.groups()) != model:
        out.append(f"BarrettHand masses: README {masses and masses.groups()}, model {model}")
    return out


def test_the_readme_says_what_the_model_uses() -> None:
    problems = mismatches(README.read_text(encoding="utf-8"))
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize(
    ("old", "new", "problem"),
    [
        ("| 1 | 0.2005 | y |", "| 1 | 0.2050 | y |", "LWR4+ joint 1"),
        ("| 3 | 0.20 | −y |", "| 3 | 0.20 | y |", "LWR4+ joint 3"),
        ("| 6 | 0.078 | z | ±170 | 180 | 60 |", "| 6 | 0.078 | z | ±170 | 180 | 100 |", "LWR4+ joint 6"),
        ("| −z | 0 … 0.8377 |", "| −z | 0 … 0.8737 |", "BarrettHand distal (each finger): README range"),
        ("palm (0, −0.05, 0.0754)", "palm (0, 0.05, 0.0754)", "BarrettHand finger 3 proximal: README origin"),
        ("1.17335; −0.00045", "1.17353; −0.00045", "arm mount right"),
        ("limits ±1.57, velocity", "limits ±1.75, velocity", "Structure: /limits"),
        ("at (0.0105, −0.001, 1.3117)", "at (0.0105, −0.001, 1.3171)", "Structure: head_base"),
        ("proximal 0.058 kg", "proximal 0.085 kg", "BarrettHand masses"),
    ],
)
def test_a_number_changed_in_a_copy_of_the_readme_is_caught(old: str, new: str, problem: str) -> None:
    text = README.read_text(encoding="utf-8")
    assert text.count(old) == 1, old
    problems = mismatches(text.replace(old, new))
    assert len(problems) == 1 and problems[0].startswith(problem), problems


def test_the_readme_s_links_reach_their_headings() -> None:
    repo = doccheck.Repository(ROOT)
    text = README.read_text(encoding="utf-8")
    assert "](#sources)" in text  # not a vacuous pass: it links its own sections
    findings = doccheck.link_findings(text, README, repo)
    assert not findings, "\n".join(map(str, findings))
    broken = doccheck.link_findings(text.replace("](#sources)", "](#source)", 1), README, repo)
    assert [f.message.split(":")[0] for f in broken] == ["link to #source"]
