"""The message kinds Zenoh's access control names in its rules (eclipse-zenoh 1.10
DEFAULT_CONFIG.json5, ``access_control.rules[].messages``): what services/spec_check/acl.py
grants per agent and what the router's own link is allowed (services/runtime/zenoh_config.py)."""

from __future__ import annotations

from typing import Literal, get_args

Message = Literal[
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
]
ACL_MESSAGES: tuple[Message, ...] = get_args(Message)
"""Every kind of :data:`Message`, in that order."""
