"""The 22 communicative acts of the FIPA Communicative Act Library (FIPA SC00037).

The paper's set of performative verbs V̂ (paper §3.3) is exactly this set.
"""

from __future__ import annotations

import enum


class Performative(enum.StrEnum):
    """A FIPA performative; the value is the FIPA SC00061 spelling (lower case, hyphenated)."""

    ACCEPT_PROPOSAL = "accept-proposal"
    AGREE = "agree"
    CANCEL = "cancel"
    CFP = "cfp"
    CONFIRM = "confirm"
    DISCONFIRM = "disconfirm"
    FAILURE = "failure"
    INFORM = "inform"
    INFORM_IF = "inform-if"
    INFORM_REF = "inform-ref"
    NOT_UNDERSTOOD = "not-understood"
    PROPAGATE = "propagate"
    PROPOSE = "propose"
    PROXY = "proxy"
    QUERY_IF = "query-if"
    QUERY_REF = "query-ref"
    REFUSE = "refuse"
    REJECT_PROPOSAL = "reject-proposal"
    REQUEST = "request"
    REQUEST_WHEN = "request-when"
    REQUEST_WHENEVER = "request-whenever"
    SUBSCRIBE = "subscribe"


ALL_PERFORMATIVES: frozenset[Performative] = frozenset(Performative)
