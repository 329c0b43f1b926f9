"""Making the hands safe after a take or a set-down was interrupted.

A take — reach, grasp, held, lift, withdraw — is an atomic state of the plan's HFSM (paper
§3.2). When it is interrupted before the grasp completed (a_ta restarted inside it, or ag_ex
held position because a_ta looked gone), the open or half-closed hand stands around the
object, often inside a cabinet. a_km does not know the object is in the hand's way (nothing is
held), so the next plan begins with a torso turn or a joint move that drags the object out and
drops it. Before a_ta reports the plan's end it therefore opens the hand as the plan opened it
and moves it back, pose by pose, along the way the plan brought it in (the inverse of the
fetch's approach: reach, pregrasp, enter). A take interrupted after its grasp is finished by the
next plan instead (``services.agents.planner.domain.finish_takes``).

A set-down (lower, release, put, clear; atomic) interrupted once the hand opened is finished
instead: the release is sent again if it was the leaf running, a_km is told where the object
was put, and the empty hand makes the set-down's remaining moves and those right after it (the
park out of the way), as the plan would have: the next plan does not know where that hand is,
and a hand left beside the object is in the way of what comes next (a pour into it).
"""

from __future__ import annotations

from collections.abc import Sequence

from shared.fipa_codec.languages.l_ex import Arm, Grasp, MoveJoints, MoveTool, Release
from shared.fipa_codec.languages.l_hfsm import Assert, Execute, PlanNode

RetreatCommand = Release | MoveTool
RetreatStep = Release | MoveTool | Assert


def _command(node: PlanNode) -> object | None:
    action = node.action
    return action.command if isinstance(action, Execute) else None


def retreat(
    leaves: Sequence[tuple[str, PlanNode]], atomic_spans: Sequence[tuple[int, int]], index: int
) -> tuple[RetreatStep, ...]:
    """What makes the hands safe after leaf ``index`` was interrupted: :func:`undo_take` if
    it lies in a take before its grasp, else :func:`finish_set_down` (``()``: nothing)."""
    return undo_take(leaves, atomic_spans, index) or finish_set_down(leaves, atomic_spans, index)


def finish_set_down(
    leaves: Sequence[tuple[str, PlanNode]], atomic_spans: Sequence[tuple[int, int]], index: int
) -> tuple[RetreatStep, ...]:
    """The rest of a set-down interrupted at leaf ``index`` once its release was reached.

    Returns ``()`` unless ``index`` lies in an atomic state with a ``release`` at or before
    it (and no grasp after that release), or in the moves of the released hand that follow
    such a state (its park: held there, the hand stood beside the bowl and the next plan's
    pour brought the jar into it — chaos across hosts, the robot's router killed). Otherwise:
    that release again if it was the leaf running, then from ``index`` on, each ``Assert``
    (a_km learns where the object was put) and each tool move of the released arm, up to the
    first leaf that is neither."""
    if not 0 <= index < len(leaves):
        return ()
    span = next(((a, b) for a, b in atomic_spans if a <= index < b), None)
    after = None if span is not None else max((s for s in atomic_spans if s[1] <= index), default=None)
    span = span or after
    if span is None:
        return ()
    released: Release | None = None
    for j in range(span[0], min(index, span[1] - 1) + 1):
        cmd = _command(leaves[j][1])
        if isinstance(cmd, Release):
            released = cmd
        elif isinstance(cmd, Grasp) and released is not None and cmd.arm == released.arm:
            released = None
    if released is None:
        return ()
    if after is not None and not all(
        isinstance(node.action, Assert) or _moves(node, released) for _, node in leaves[after[1] : index + 1]
    ):
        return ()
    out: list[RetreatStep] = []
    if _command(leaves[index][1]) == released:
        out.append(released)
        index += 1
    for _path, node in leaves[index:]:
        cmd = _command(node)
        if isinstance(node.action, Assert):
            out.append(node.action)
        elif isinstance(cmd, MoveTool) and cmd.arm == released.arm:
            out.append(cmd)
        else:
            break
    return tuple(out)


def _moves(node: PlanNode, released: Release) -> bool:
    """``node`` is a tool move of the arm that ``released`` opened."""
    cmd = _command(node)
    return isinstance(cmd, MoveTool) and cmd.arm == released.arm


def undo_take(
    leaves: Sequence[tuple[str, PlanNode]], atomic_spans: Sequence[tuple[int, int]], index: int
) -> tuple[RetreatCommand, ...]:
    """The L_EX commands that withdraw the hand from the take leaf ``index`` interrupted.

    ``leaves``: the plan's leaf states in execution order (``PlanNode.leaves``);
    ``atomic_spans``: their atomic ranges ``[start, end)`` (``PlanNode.atomic_spans``);
    ``index``: the leaf that was running. Returns ``()`` unless that leaf is a tool move or a
    grasp inside an atomic state whose grasp (of that arm, at or after ``index``) has not
    completed, preceded by the ``release``
    that opened the hand for it. Otherwise returns that release again (same arm, same opening),
    then a tool move back to each earlier target since the release (or since a joint move
    after it), latest first; each takes the duration of the forward move it undoes (s)."""
    if not 0 <= index < len(leaves):
        return ()
    span = next(((a, b) for a, b in atomic_spans if a <= index < b), None)
    current = _command(leaves[index][1])
    if span is None or not isinstance(current, MoveTool | Grasp):
        return ()
    arm: Arm = current.arm
    ahead = (_command(node) for _path, node in leaves[index : span[1]])
    if not any(isinstance(cmd, Grasp) and cmd.arm == arm for cmd in ahead):
        return ()  # not a take (a set-down's moves)
    moves: list[MoveTool] = [current] if isinstance(current, MoveTool) else []
    opening: float | None = None
    retracing = True  # a joint move since the release ends the way back there
    for j in range(index - 1, -1, -1):
        cmd = _command(leaves[j][1])
        if isinstance(cmd, Grasp) and cmd.arm == arm:
            return ()  # the hand closed on the object: the take is finished, not undone
        if isinstance(cmd, MoveJoints):
            retracing = False
        elif isinstance(cmd, MoveTool) and cmd.arm == arm and retracing:
            moves.append(cmd)
        elif isinstance(cmd, Release) and cmd.arm == arm:
            opening = cmd.opening
            break
    if opening is None:
        return ()
    # moves: latest first; moves[0] is where the hand is (or is going), so go back to the
    # targets after it, each over the time the move away from it took
    back = tuple(
        MoveTool(arm=arm, target=moves[i + 1].target, duration=moves[i].duration)
        for i in range(len(moves) - 1)
    )
    return (Release(arm=arm, opening=opening), *back)
