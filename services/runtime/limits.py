"""Limits on what one agent accepts from the others ("Bad input"; docs/security.md).

- The largest communicate: :data:`~shared.fipa_codec.encoding.MAX_COMMUNICATE_BYTES`
  (4 MiB of encoded msgpack), enforced by the codec on encode and decode and, with
  :func:`low_pass_filter`, by the Zenoh router, which then drops a larger publication on any
  ``roco/**`` key before it reaches an agent.
- Open conversations per peer: :data:`MAX_OPEN_CONVERSATIONS_PER_PEER`. A peer that opens one
  more (a new conversation-id with an opening performative) while it already has that many
  open with the agent gets ``refuse`` (FIPA SC00037 §3.17: the agent will not perform the
  action; the reason is the content, UTF-8 text), or ``not-understood`` where its protocol has
  no ``refuse``.
- The reasons a received communicate is rejected, each counted in the agent's ``counters`` as
  ``rejected.<reason>`` (:data:`REJECT_REASONS`); ``roco status`` shows them
  (:data:`~services.runtime.keys.COUNTERS_ASK`).
"""

from __future__ import annotations

from typing import Any

from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES

MAX_OPEN_CONVERSATIONS_PER_PEER = 128
"""Open conversations (not yet in a final protocol state) one agent keeps with one peer, both
directions counted. The Robot Companion needs a handful per peer (one command, plan or
subscription each; paper Table 7); 128 leaves room for a queue of commands and retries while
keeping a flooding peer from pushing everyone else's conversations out of the agent's
protocol-state table (``ProtocolStates.max_open``, 1024)."""

REJECT_REASONS: dict[str, str] = {
    "bad_key": "the key is not roco/fipa/<channel>/<sender>/<receiver> (dropped, nobody to answer)",
    "malformed": "the bytes are not a communicate (not msgpack, wrong types, unknown performative…)",
    "oversized": f"the communicate is larger than {MAX_COMMUNICATE_BYTES} bytes",
    "sender_mismatch": "the sender parameter differs from the sender in the key",
    "not_in_interface": "performative/protocol/channel outside the agent's specified interface",
    "language": "a content language the interface does not accept for this communicate",
    "ontology": "the ontology is not its content language's (O_RoCo; O_Velma for L_EX)",
    "content": "the content does not decode in its language (or is nested too deeply)",
    "content_type": "a term of the language the interface does not allow for this communicate",
    "protocol_state": "not allowed in its conversation's current protocol state",
    "no_conversation_id": "a communicate in a followed interaction protocol without a conversation-id",
    "too_many_conversations": "a new conversation beyond MAX_OPEN_CONVERSATIONS_PER_PEER (refused)",
    "unhandled": "allowed by the specification but not expected by the agent in its current state",
    "internal": "handling it raised inside the runtime (a bug; logged with its traceback)",
}
"""``rejected.<reason>`` counters of :class:`services.runtime.agent.Agent`, with what each
means. ``rejected`` (no suffix) counts every not-understood the agent sent; ``duplicates``
counts byte-identical copies (dropped and answered again, services/runtime/dedup.py)."""


def low_pass_filter(
    max_bytes: int = MAX_COMMUNICATE_BYTES, key_exprs: tuple[str, ...] = ("roco/**",)
) -> list[dict[str, Any]]:
    """The Zenoh (1.x) ``low_pass_filter`` configuration that makes a router drop every
    message on ``key_exprs`` whose payload exceeds ``max_bytes`` (bytes; a payload of exactly
    ``max_bytes`` passes), in both directions, for put, delete, query and reply.

    Use: ``conf.insert_json5("low_pass_filter", json.dumps(low_pass_filter()))`` on the
    router's :class:`zenoh.Config` (zenoh DEFAULT_CONFIG.json5, ``low_pass_filter``; checked
    against eclipse-zenoh 1.10: an unknown field or message kind is refused by
    ``insert_json5``). Raises ValueError for a ``max_bytes`` below 1 or no key expression.
    """
    if max_bytes < 1:
        raise ValueError(f"max_bytes must be at least 1, not {max_bytes}")
    if not key_exprs:
        raise ValueError("low_pass_filter needs at least one key expression")
    return [
        {
            "id": "roco-max-communicate",
            "flows": ["ingress", "egress"],
            "messages": ["put", "delete", "query", "reply"],
            "key_exprs": list(key_exprs),
            "size_limit": max_bytes,
        }
    ]
