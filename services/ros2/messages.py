"""roco's own ROS 2 interfaces (package ``roco_msgs``) as ``.msg``/``.srv`` text, and the rosbags
type store that holds them beside ROS 2 Jazzy's standard types.

The definitions follow ROS 2's interface format (design.ros2.org "Interface definition"; field
names in snake case, ``#`` comments). Their type hashes (REP 2011, RIHS01) are computed by
rosbags (``Typestore.hash_rihs01``), never written down here. The service ``roco_msgs/srv/Say``
is text only (:data:`SAY_SRV`): rosbags' type store holds messages, not services. Importing this
module needs nothing; :func:`typestore` needs the ``ros2`` extra (rosbags) and raises
:class:`MissingExtra` without it.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

PACKAGE = "roco_msgs"
COMMUNICATE = "roco_msgs/msg/Communicate"
TASK_STATE = "roco_msgs/msg/TaskState"
SAY_PROGRESS = "roco_msgs/msg/SayProgress"
SAY = "roco_msgs/srv/Say"

EXTRA_HINT = "pip install -e '.[ros2]' (rosbags, mcap, mcap-ros2-support)"

COMMUNICATE_MSG = """\
# One FIPA ACL communicate (FIPA SC00061) as roco's traffic recorder saw it cross Zenoh
# (services/recorder/record.py TrafficRecord and RawEntry): enough to rebuild both exactly.
builtin_interfaces/Time stamp  # robot time (sim_time) when the run gives it, else zero
float64 wall_time              # POSIX s: when it crossed Zenoh (the record's t)
string key                     # Zenoh key expression, roco/fipa/<channel>/<sender>/<receiver>
string channel                 # C1..C9, or ? for a key that is no communicate key
uint32 size                    # payload bytes on the wire
# the 13 message parameters (FIPA SC00061 2); an absent text parameter is ""
string performative            # one of FIPA SC00037's 22 acts, or malformed
string sender
string[] receiver
string[] reply_to
string content                 # the content as text: JSON of its term, else its UTF-8, else base64
string language
string encoding
string ontology
string protocol
string conversation_id
string reply_with
string in_reply_to
float64 reply_by               # POSIX s; NaN when absent
# the recorder's entry
string incarnation             # recorder process that wrote it; "" before incarnations
uint64 seq                     # index in the run's record
string source                  # Zenoh publisher <session id>:<entity id>; "" when none
int64 sn                       # the publisher's sequence number; -1 when none
float64 t_sent                 # the publisher's timestamp, POSIX s; NaN when none
bool late                      # recovered from the publisher's cache
string key_sender              # the sender the key names; "" when none
uint32 part                    # place in the batch its sample carried
uint8[] payload                # the communicate's msgpack bytes as received; empty when lost
"""

TASK_STATE_MSG = """\
# Where one command stands (a_co's task state, paper Table 3; L_HC Progress).
builtin_interfaces/Time stamp
string command_id              # the command's C2 conversation-id
string text                    # the command as said
# waiting, planning, running, terminating, preempted, succeeded, failed or stopped
string state
# the plan's HFSM state being executed, pour(jar,bowl)/fetch_jar/take/grasp; "" when none
string step
# state and step as roco prints them, Running pour(jar,bowl)/fetch_jar/take/grasp
string path
string detail                  # why, in words a person can read
"""

SAY_PROGRESS_MSG = """\
# Progress of a sentence given to a_hi (roco_msgs/srv/Say), at every change.
builtin_interfaces/Time stamp
string sentence                # the sentence as given
string command_id              # its command's C2 conversation-id; "" until a_co accepts it
string state                   # as roco_msgs/msg/TaskState state
string step                    # as roco_msgs/msg/TaskState step
string detail
"""

SAY_REQUEST_MSG = """\
string sentence                # what a person says to the robot, pour the jar into the bowl
"""

SAY_RESPONSE_MSG = """\
bool ok                        # the command succeeded (or the question was answered)
# a_hi's report kind: accepted, not-understood, succeeded, failed, stopped, status or answer
string outcome
string report                  # the readable sentences a_hi would say
"""

SAY_SRV = f"{SAY_REQUEST_MSG}---\n{SAY_RESPONSE_MSG}"
"""``roco_msgs/srv/Say`` as ``.srv`` text: the request, ``---``, the response."""

MESSAGES: dict[str, str] = {
    COMMUNICATE: COMMUNICATE_MSG,
    TASK_STATE: TASK_STATE_MSG,
    SAY_PROGRESS: SAY_PROGRESS_MSG,
}
"""Every roco_msgs message type → its ``.msg`` text."""


class MissingExtra(RuntimeError):
    """The ``ros2`` extra (rosbags, mcap, mcap-ros2-support) is not installed."""


def missing_extra(modules: tuple[str, ...] = ("rosbags",)) -> str | None:
    """None when every one of ``modules`` (of the ``ros2`` extra; the live face needs rosbags)
    can be imported; else one line naming the missing ones and how to install them."""
    import importlib.util

    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if not missing:
        return None
    return f"ROS 2 needs the ros2 extra: {EXTRA_HINT} (missing: {', '.join(missing)})"


@functools.cache
def typestore() -> Typestore:
    """ROS 2 Jazzy's types (rosbags ``Stores.ROS2_JAZZY``) plus :data:`MESSAGES`, built once.
    Raises MissingExtra without rosbags."""
    try:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    except ImportError as exc:
        raise MissingExtra(f"ROS 2 formats need the ros2 extra: {EXTRA_HINT} ({exc})") from None
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in MESSAGES.items():
        store.register(get_types_from_msg(text, name))
    return store


def message_definition(typename: str) -> str:
    """The ``ros2msg`` schema text of ``typename`` as rosbag2 writes it in an MCAP file: its
    definition, then each type it uses after a ``MSG:`` separator line (rosbags
    ``generate_msgdef``). Raises KeyError for an unknown type, MissingExtra without rosbags."""
    store = typestore()
    if typename not in store.fielddefs:
        raise KeyError(typename)
    text, _ = store.generate_msgdef(typename, ros_version=2)
    return text


def type_hash(typename: str) -> str:
    """The RIHS01 type hash of ``typename`` (REP 2011), ``RIHS01_<64 hex digits>``, computed by
    rosbags. Raises KeyError for an unknown type, MissingExtra without rosbags."""
    store = typestore()
    if typename not in store.fielddefs:
        raise KeyError(typename)
    return store.hash_rihs01(typename)
