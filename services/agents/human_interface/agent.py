"""a_hi — the human interface (paper §5.2): takes commands from a person, reports progress.

Receptor: ``roco/human/in`` (:class:`HumanInput`, sentences). Effector: ``roco/human/out``
(:class:`HumanReport`). Towards a_co, on C2 in L_HC, a_hi initiates three protocols:

- **fipa-request** per command: ``request`` a :class:`HumanCommand`; a_co ``agree``\\s (or
  ``refuse``\\s) and ends with ``inform``/``failure`` :class:`CommandOutcome`. A stop
  request ("stop") sends ``cancel`` in every open command's conversation (the cancel
  meta-protocol); a_co answers the cancel with ``inform`` (stopped) or ``failure``.
- **fipa-subscribe** once: ``subscribe`` a :class:`ProgressSubscription` at start-up; a_co
  agrees and informs a :class:`Progress` at every change of a command's state. While a_co
  does not agree (not up yet, or an a_co that does not serve subscriptions), a_hi retries
  quietly, each attempt in a new conversation, with a growing interval; a_co's liveliness
  token appearing triggers an attempt at once. Commands work without the subscription.
- **fipa-query** per status request ("what are you doing?"): ``query-ref`` a
  :class:`StatusQuery`; a_co answers ``inform-ref`` a :class:`Status`.

Every request from the person (command, stop, status) gets reports under its own
``request_id`` and ends with one report of a kind in FINAL_REPORTS (messages.py).

Restarts (issue 7; docs/recovery.md): a command's request is retransmitted until a_co agrees
(a_co may be restarting; its runtime drops copies and answers them again). a_hi keeps its open
commands in its state file; a restarted a_hi takes them back, so a_co's outcome still reaches
the person who asked. Open stop requests and status queries are not kept (ask again).
"""

from __future__ import annotations

import time
from collections import OrderedDict
from dataclasses import dataclass, field

import msgspec

from services.agents.human_interface.language import (
    Command,
    NotUnderstood,
    StatusRequest,
    Stop,
    describe,
    interpret,
)
from services.runtime import keys
from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.conversations import Pending
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind, RequestKind
from services.runtime.state_store import StateFile
from shared.fipa_codec import DecodeError, Performative, decode
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    ProgressSubscription,
    Status,
    StatusQuery,
    TaskState,
    TaskStatus,
)

CO = "a_co"
REQUEST = "fipa-request"
SUBSCRIBE = "fipa-subscribe"
QUERY = "fipa-query"

AGREE_BY_S = 120.0
"""How long a_co has to agree to (or refuse) a command."""
COMMAND_RETRY_S = 5.0
"""Retransmission period of a command's request until a_co answers it."""
COMMAND_REPLY_BY_S = 3600.0
"""How long an agreed command may take before a_hi gives up on it."""
CANCEL_REPLY_BY_S = 300.0
"""How long a_co has to answer a cancel (the robot first puts down what it holds)."""
STATUS_REPLY_BY_S = 10.0
"""How long a_co has to answer a status query."""
SUBSCRIBE_REPLY_BY_S = 5.0
"""How long one subscription attempt waits for a_co's agree."""
SUBSCRIBE_RETRY_S = (1.0, 60.0)
"""First and longest interval between subscription attempts (doubling in between)."""
SUBSCRIPTION = "hi-progress"
"""Conversation-id of the first subscription attempt; later ones add ``-2``, ``-3``, …"""
ENDED_KEPT = 256
"""How many ended command conversations a_hi remembers (late replies, late progress)."""

_CONNECTIVES = frozenset(
    {"for", "by", "because", "after", "before", "while", "since", "until", "as", "so", "with", "to"}
)


class KeptCommand(msgspec.Struct, kw_only=True):
    """An open command as a_hi keeps it across a restart: the request as sent (encoded
    communicate and its Zenoh key), the person's request id, its label, whether a_co agreed."""

    request: bytes
    key: str
    request_id: str
    label: str
    agreed: bool


class KeptHumanInterface(msgspec.Struct, kw_only=True):
    """a_hi's state file: its open commands."""

    commands: list[KeptCommand]


@dataclass(frozen=True)
class PeerAlive:
    """Receptor event: a_co's liveliness token appeared (``alive``) or disappeared."""

    alive: bool


@dataclass
class OpenCommand:
    """A command sent to a_co and not yet ended. ``conversation_id`` is its C2
    conversation (a_co's ``command_id``); ``reply_with`` that of the request; ``cancel``
    that of an outstanding cancel; ``stoppers`` the stop requests waiting for its end."""

    conversation_id: str
    request_id: str
    command: HumanCommand
    label: str
    reply_with: str
    agreed: bool = False
    sent: tuple[str, bytes] = ("", b"")  # Zenoh key and bytes of the request
    cancel: str | None = None
    stoppers: list[str] = field(default_factory=list)
    last: Progress | None = None


@dataclass
class StopRequest:
    """A person's "stop": the commands whose end it awaits (conversation → label) and one
    line per command that has ended; ``failed`` when one could not be stopped."""

    request_id: str
    waiting: dict[str, str]
    lines: list[str] = field(default_factory=list)
    failed: bool = False


def sentence(label: str, word: str, detail: str = "") -> str:
    """``label: word`` followed by ``detail`` readably: "pour the jar into the bowl:
    stopped; the jar was put down on the table", "…: preempted for 'bring the cup …'"."""
    detail = " ".join(detail.split())
    if not detail:
        return f"{label}: {word}"
    if detail.lower().startswith(word.lower()):
        return f"{label}: {detail}"
    if detail.split()[0].lower() in _CONNECTIVES:
        return f"{label}: {word} {detail}"
    return f"{label}: {word}; {detail}"


_AT_STEP = frozenset({TaskState.RUNNING, TaskState.TERMINATING, TaskState.PREEMPTED})
"""States in which the plan's step says where the robot is (elsewhere it is a stale one)."""


def state_words(state: TaskState, step: str | None) -> str:
    """ "running pour(jar,bowl)/fetch_jar/grasp", "planning", …"""
    return f"{state.value} {step}" if step and state in _AT_STEP else state.value


def progress_text(label: str, progress: Progress) -> str:
    """A :class:`Progress` as a sentence ("…: running pour(jar,bowl)/fetch_jar/grasp")."""
    return sentence(label, state_words(progress.state, progress.step), progress.detail)


def status_line(label: str, task: TaskStatus) -> str:
    """One line of a status report: a command, its state and step, priority, deadline."""
    parts = [state_words(task.state, task.step)]
    if task.priority:
        parts.append(f"priority {task.priority}")
    if task.deadline_in_s is not None:
        if task.deadline_in_s >= 0:
            parts.append(f"{task.deadline_in_s:.0f} s left to its deadline")
        else:
            parts.append(f"deadline missed by {-task.deadline_in_s:.0f} s")
    return f"{label}: {', '.join(parts)}"


def _reason(item: Received) -> str:
    """Why a_co answered ``item`` negatively, in words."""
    if item.local:
        return "a_co did not answer in time"
    if isinstance(item.content, CommandOutcome):
        return item.content.detail or "no reason given"
    text = item.msg.content.decode("utf-8", "replace").strip() if item.msg.content else ""
    return text or "no reason given"


class HumanInterface(Agent):
    """a_hi: sentences in, L_HC on C2 to a_co, readable reports out."""

    name = "a_hi"

    def build_fsm(self) -> FSM:
        self.commands: dict[str, OpenCommand] = {}  # conversation-id → open command
        self.asked: dict[str, RequestKind] = {}  # person's request id → what it was, until its final report
        self.ended: OrderedDict[str, tuple[str, str]] = OrderedDict()  # conversation → (request, label)
        self.cancels: dict[str, str] = {}  # reply-with of a cancel → command conversation
        self.stops: dict[str, StopRequest] = {}  # request_id → stop request
        self.queries: dict[str, str] = {}  # status query conversation → request_id
        self.subscribed = False
        self.subscription: str | None = None  # conversation of the latest attempt
        self.sub_pending: str | None = None  # reply-with of the unanswered latest attempt
        self.sub_attempts = 0
        self.retry_at: float | None = None
        self.retry_interval = SUBSCRIBE_RETRY_S[0]
        self.co_alive = False  # a_co's liveliness token is present
        self.kept = StateFile.for_agent(self.name, KeptHumanInterface)
        return FSM(
            initial="interact",
            states={
                "interact": Behaviour(
                    "interact",
                    self._interact,
                    terminal=lambda: False,
                    doc="turn sentences into requests, cancels and queries to a_co; "
                    "report a_co's answers and progress to the person",
                )
            },
        )

    def setup(self) -> None:
        decoder = msgspec.json.Decoder(HumanInput)

        def on_text(key: str, payload: bytes) -> None:
            try:
                self.post(decoder.decode(payload))
            except msgspec.DecodeError as exc:
                self.log.warning("ignored malformed human input: %s", exc)

        self.transport.subscribe(keys.HUMAN_IN, on_text)
        kept = self.kept.load()
        if kept is not None:
            self._restore(kept)
        self._subscribe()
        self.transport.watch(keys.alive_key(CO), lambda key, alive: self.post(PeerAlive(alive)))

    # ---- restarts ----------------------------------------------------------------------
    def persist(self) -> None:
        self.kept.save(
            KeptHumanInterface(
                commands=[
                    KeptCommand(
                        request=c.sent[1],
                        key=c.sent[0],
                        request_id=c.request_id,
                        label=c.label,
                        agreed=c.agreed,
                    )
                    for c in self.commands.values()
                    if c.sent[1]
                ]
            )
        )

    def _restore(self, kept: KeptHumanInterface) -> None:
        """Take back the open commands of a previous a_hi; retransmit those not yet agreed."""
        now = time.time()
        for k in kept.commands:
            try:
                msg = decode(k.request)
            except DecodeError as exc:
                self.log.warning("a kept command does not decode (%s): dropped", exc)
                continue
            cid, reply_with = msg.conversation_id, msg.reply_with
            if cid is None or reply_with is None:
                continue
            try:
                command = decode_content(msg.language or "", msg.content)
            except ContentError as exc:
                self.log.warning("kept command %s does not decode (%s): dropped", cid, exc)
                continue
            if not isinstance(command, HumanCommand):
                continue
            history = [(Performative.REQUEST, True)] + ([(Performative.AGREE, False)] if k.agreed else [])
            self.restore_conversation(CO, cid, REQUEST, history)
            self.commands[cid] = OpenCommand(
                cid, k.request_id, command, k.label, reply_with, agreed=k.agreed, sent=(k.key, k.request)
            )
            self.conversations.expect(
                Pending(
                    reply_with,
                    CO,
                    REQUEST,
                    cid,
                    now + (COMMAND_REPLY_BY_S if k.agreed else AGREE_BY_S),
                    retry_s=None if k.agreed else COMMAND_RETRY_S,
                    key=k.key,
                    payload=k.request,
                    next_retry=None if k.agreed else now,
                )
            )
        if self.commands:
            self.log.info("restored %d open command(s) from %s", len(self.commands), self.kept.path)

    # ---- the behaviour -----------------------------------------------------------------
    def _interact(self) -> None:
        while self.r:
            event = self.r.popleft()
            if isinstance(event, HumanInput):
                self._on_input(event)
            elif isinstance(event, PeerAlive):
                self._on_peer(event.alive)
        while self.x:
            item = self.x.popleft()
            try:
                self._on_communicate(item)
            except Exception:  # one bad communicate must not cost the others their answers
                self.counters["handler_errors"] += 1
                self.log.exception("handling %s from %s failed", item.performative.value, item.sender)
        if (
            not self.subscribed
            and self.sub_pending is None
            and self.retry_at is not None
            and time.time() >= self.retry_at
        ):
            self._subscribe()

    def _report(self, request_id: str, kind: ReportKind, text: str) -> None:
        self.log.info("to person [%s] %s: %s", request_id, kind.value, text)
        request = self.asked.pop(request_id, None) if kind in FINAL_REPORTS else self.asked.get(request_id)
        report = HumanReport(request_id=request_id, kind=kind, text=text, request=request)
        self.emit(keys.HUMAN_OUT, msgspec.json.encode(report))

    # ---- from the person ---------------------------------------------------------------
    def _on_input(self, event: HumanInput) -> None:
        try:
            intent = interpret(event.text, priority=event.priority)
        except NotUnderstood as exc:
            self._report(event.request_id, ReportKind.NOT_UNDERSTOOD, str(exc))
            return
        if isinstance(intent, Command):
            self.asked[event.request_id] = RequestKind.COMMAND
            self._command(event, intent)
        elif isinstance(intent, Stop):
            self.asked[event.request_id] = RequestKind.STOP
            self._stop_commands(event.request_id)
        elif isinstance(intent, StatusRequest):
            self.asked[event.request_id] = RequestKind.STATUS
            self._ask_status(event.request_id)

    def _conversation_id(self, prefix: str, request_id: str) -> str:
        base = f"{prefix}-{request_id}"
        cid, n = base, 1
        while cid in self.commands or cid in self.ended or cid in self.queries:
            n += 1
            cid = f"{base}-{n}"
        return cid

    def _command(self, event: HumanInput, intent: Command) -> None:
        command = HumanCommand(
            text=event.text, goal=intent.goal, priority=intent.priority, deadline_s=intent.deadline_s
        )
        msg = self.send(
            CO,
            Performative.REQUEST,
            command,
            protocol=REQUEST,
            conversation_id=self._conversation_id("cmd", event.request_id),
            reply_by_s=AGREE_BY_S,
            retry_s=COMMAND_RETRY_S,
        )
        assert msg.conversation_id is not None and msg.reply_with is not None
        pending = self.conversations.get(msg.reply_with)  # it keeps the bytes to retransmit
        assert pending is not None
        if not self.co_alive:
            self.log.warning(
                "a_co is not known to be alive; %s may wait %.0f s", msg.conversation_id, AGREE_BY_S
            )
        self.commands[msg.conversation_id] = OpenCommand(
            msg.conversation_id,
            event.request_id,
            command,
            describe(intent.goal),
            msg.reply_with,
            sent=(pending.key, pending.payload),
        )

    def _stop_commands(self, request_id: str) -> None:
        if not self.commands:
            self._report(request_id, ReportKind.STOPPED, "Nothing is running, so there is nothing to stop.")
            return
        stop = StopRequest(request_id, {c.conversation_id: c.label for c in self.commands.values()})
        self.stops[request_id] = stop
        for c in self.commands.values():
            c.stoppers.append(request_id)
            if c.cancel is not None:
                continue  # a cancel is already on its way; wait for its answer
            msg = self.send(
                CO,
                Performative.CANCEL,
                c.command,
                protocol=REQUEST,
                conversation_id=c.conversation_id,
                reply_by_s=CANCEL_REPLY_BY_S,
            )
            assert msg.reply_with is not None
            c.cancel = msg.reply_with
            self.cancels[msg.reply_with] = c.conversation_id
            self._report(c.request_id, ReportKind.PROGRESS, f"{c.label}: stopping, as you asked")
        n = len(stop.waiting)
        self._report(
            request_id,
            ReportKind.PROGRESS,
            f"Stopping {n} command{'s' if n > 1 else ''}: {'; '.join(stop.waiting.values())}.",
        )

    def _ask_status(self, request_id: str) -> None:
        msg = self.send(
            CO,
            Performative.QUERY_REF,
            StatusQuery(),
            protocol=QUERY,
            conversation_id=self._conversation_id("status", request_id),
            reply_by_s=STATUS_REPLY_BY_S,
        )
        assert msg.conversation_id is not None
        self.queries[msg.conversation_id] = request_id

    # ---- from a_co ---------------------------------------------------------------------
    def _on_communicate(self, item: Received) -> None:
        cid = item.msg.conversation_id or ""
        if item.sender == CO and item.msg.protocol == SUBSCRIBE:
            self._on_subscription(item)
        elif item.msg.in_reply_to is not None and item.msg.in_reply_to in self.cancels:
            self._on_cancel_answer(item)
        elif cid in self.commands:
            self._on_command_answer(self.commands[cid], item)
        elif cid in self.ended:
            self.log.debug("late %s in ended conversation %s", item.performative.value, cid)
        elif cid in self.queries:
            self._on_status_answer(item)
        elif not item.local and item.performative is not Performative.NOT_UNDERSTOOD:
            self.not_understood(
                item.sender, item.channel, f"no such conversation of a_hi: {cid or '(none)'}", item.msg
            )

    def _on_command_answer(self, c: OpenCommand, item: Received) -> None:
        perf = item.performative
        if perf is Performative.AGREE:
            if not c.agreed:
                c.agreed = True
                # the agree answers the request; the outcome may take much longer
                self.conversations.expect(
                    Pending(
                        c.reply_with,
                        CO,
                        REQUEST,
                        c.conversation_id,
                        time.time() + COMMAND_REPLY_BY_S,
                    )
                )
                extras = []
                if c.command.priority:
                    extras.append(f"priority {c.command.priority}")
                if c.command.deadline_s is not None:
                    extras.append(f"within {c.command.deadline_s:g} s")
                more = f" ({', '.join(extras)})" if extras else ""
                self._report(c.request_id, ReportKind.ACCEPTED, f"I will {c.label}{more}.")
            return
        stopping = c.cancel is not None or bool(c.stoppers)
        if perf is Performative.INFORM:
            outcome = item.content if isinstance(item.content, CommandOutcome) else None
            if outcome is None or outcome.succeeded:
                self._end(
                    c, ReportKind.SUCCEEDED, sentence(c.label, "succeeded", outcome.detail if outcome else "")
                )
            elif stopping:
                self._end(c, ReportKind.STOPPED, sentence(c.label, "stopped", outcome.detail))
            else:
                self._end(c, ReportKind.FAILED, sentence(c.label, "failed", outcome.detail))
        elif perf is Performative.FAILURE:
            if item.local:
                waited = COMMAND_REPLY_BY_S if c.agreed else AGREE_BY_S
                reason = f"a_co did not {'finish' if c.agreed else 'answer'} within {waited:.0f} s"
                self._end(c, ReportKind.FAILED, sentence(c.label, "failed", reason))
                return
            reason = _reason(item)
            if stopping and reason.lower().startswith("stopped"):
                self._end(c, ReportKind.STOPPED, sentence(c.label, "stopped", reason))
            else:
                self._end(c, ReportKind.FAILED, sentence(c.label, "failed", reason))
        elif perf is Performative.REFUSE:
            self._end(c, ReportKind.FAILED, sentence(c.label, "refused", _reason(item)))
        elif perf is Performative.NOT_UNDERSTOOD:
            self._end(
                c, ReportKind.FAILED, f"{c.label}: a_co did not understand the command; {_reason(item)}"
            )
        else:
            self.not_understood(item.sender, item.channel, f"unexpected {perf.value} for a command", item.msg)

    def _on_cancel_answer(self, item: Received) -> None:
        perf = item.performative
        if perf is Performative.AGREE:
            return  # not part of the cancel meta-protocol; keep waiting for the answer
        assert item.msg.in_reply_to is not None
        cid = self.cancels.pop(item.msg.in_reply_to)
        c = self.commands.get(cid)
        if c is None:
            return  # the command ended (its outcome crossed the cancel); stops were told then
        c.cancel = None
        if perf is Performative.INFORM:
            outcome = item.content if isinstance(item.content, CommandOutcome) else None
            if outcome is not None and outcome.succeeded:  # it finished before it could stop
                self._end(c, ReportKind.SUCCEEDED, sentence(c.label, "succeeded", outcome.detail))
            else:
                self._end(
                    c, ReportKind.STOPPED, sentence(c.label, "stopped", outcome.detail if outcome else "")
                )
            return
        # failure (could not cancel), not-understood, or no answer in time: it goes on
        reason = _reason(item)
        if item.local:
            reason = f"a_co did not confirm the stop within {CANCEL_REPLY_BY_S:.0f} s"
        line = sentence(c.label, "could not be stopped", reason)
        self._report(c.request_id, ReportKind.PROGRESS, line)
        self._tell_stoppers(c, line, ok=False)

    def _end(self, c: OpenCommand, kind: ReportKind, text: str) -> None:
        """Command ``c`` has ended: the final report, and every stop request waiting for it."""
        self._report(c.request_id, kind, text)
        del self.commands[c.conversation_id]
        self.conversations.forget_conversation(c.conversation_id)
        for reply_with in [k for k, v in self.cancels.items() if v == c.conversation_id]:
            del self.cancels[reply_with]
        self.ended[c.conversation_id] = (c.request_id, c.label)
        while len(self.ended) > ENDED_KEPT:
            self.ended.popitem(last=False)
        if kind is not ReportKind.STOPPED:
            text = f"{text} (it ended before it could be stopped)"
        self._tell_stoppers(c, text, ok=True)

    def _tell_stoppers(self, c: OpenCommand, line: str, *, ok: bool) -> None:
        for request_id in c.stoppers:
            stop = self.stops.get(request_id)
            if stop is None or c.conversation_id not in stop.waiting:
                continue
            del stop.waiting[c.conversation_id]
            stop.lines.append(line)
            stop.failed = stop.failed or not ok
            if not stop.waiting:
                del self.stops[request_id]
                kind = ReportKind.FAILED if stop.failed else ReportKind.STOPPED
                self._report(request_id, kind, "\n".join(stop.lines))
        c.stoppers.clear()

    def _on_status_answer(self, item: Received) -> None:
        if item.performative is Performative.AGREE:
            return
        cid = item.msg.conversation_id or ""
        request_id = self.queries.pop(cid)
        self.conversations.forget_conversation(cid)
        labels = {c.conversation_id: c.label for c in self.commands.values()}
        if item.performative in (Performative.INFORM_REF, Performative.INFORM) and isinstance(
            item.content, Status
        ):
            tasks = item.content.tasks
            if not tasks:
                text = "I am not doing anything: no command is running or waiting."
            else:
                text = "\n".join(
                    status_line(labels.get(t.command_id, repr(t.text)), t) for t in item.content.tasks
                )
            self._report(request_id, ReportKind.STATUS, text)
            return
        if item.performative in (Performative.INFORM_REF, Performative.INFORM):
            reason = "its answer held no status"
        else:
            reason = _reason(item)
        mine = [
            progress_text(c.label, c.last) if c.last else f"{c.label}: {'accepted' if c.agreed else 'sent'}"
            for c in self.commands.values()
        ]
        known = "\n".join(mine) if mine else "no command of mine is open."
        self._report(
            request_id,
            ReportKind.STATUS,
            f"a_co did not tell me its status ({reason}); from its last reports:\n{known}",
        )

    # ---- the progress subscription ---------------------------------------------------------
    def _subscribe(self) -> None:
        self.sub_attempts += 1
        cid = SUBSCRIPTION if self.sub_attempts == 1 else f"{SUBSCRIPTION}-{self.sub_attempts}"
        if self.subscription is not None:  # the previous attempt is given up (or its a_co gone)
            self.conversations.forget_conversation(self.subscription)
        msg = self.send(
            CO,
            Performative.SUBSCRIBE,
            ProgressSubscription(),
            protocol=SUBSCRIBE,
            conversation_id=cid,
            reply_by_s=SUBSCRIBE_REPLY_BY_S,
        )
        self.subscription = cid
        self.sub_pending = msg.reply_with
        self.retry_at = None

    def _retry_later(self) -> None:
        self.retry_at = time.time() + self.retry_interval
        self.retry_interval = min(self.retry_interval * 2, SUBSCRIBE_RETRY_S[1])

    def _on_peer(self, alive: bool) -> None:
        self.co_alive = alive
        if alive:
            self.retry_interval = SUBSCRIBE_RETRY_S[0]
            if not self.subscribed and self.sub_pending is None:
                self._subscribe()  # a_co (re)appeared: ask at once
            # an attempt still pending (perhaps lost before a_co was up) times out, then
            # the next one follows after the shortest interval
        elif self.subscribed:
            self.log.warning("a_co went away; progress reports pause until it is back")
            self.subscribed = False
            self.retry_interval = SUBSCRIBE_RETRY_S[0]
            self._retry_later()

    def _on_subscription(self, item: Received) -> None:
        perf = item.performative
        cid = item.msg.conversation_id or ""
        current = cid == self.subscription
        if perf is Performative.INFORM:
            if isinstance(item.content, Progress):
                if not self.subscribed and current:
                    self._subscribed()
                self._on_progress(item.content)
            elif current:
                self.not_understood(
                    item.sender, item.channel, "a progress inform carries a Progress", item.msg
                )
            return  # else: the answer to the cancel of a superfluous subscription
        if perf is Performative.AGREE:
            if current:
                self._subscribed()
            else:  # an attempt given up agreed late: the latest attempt is the one to keep
                self.send(
                    CO, Performative.CANCEL, ProgressSubscription(), protocol=SUBSCRIBE, conversation_id=cid
                )
            return
        if not current:
            return  # refuse/failure of an attempt already given up
        quiet = self.sub_attempts > 1
        (self.log.debug if quiet else self.log.info)(
            "a_co did not take the progress subscription (%s: %s); retrying in %.0f s",
            perf.value,
            _reason(item),
            self.retry_interval,
        )
        self.subscribed = False
        self.sub_pending = None
        self._retry_later()

    def _subscribed(self) -> None:
        self.subscribed = True
        self.sub_pending = None
        self.retry_at = None
        self.retry_interval = SUBSCRIBE_RETRY_S[0]
        self.log.info("a_co agreed to report progress (%s)", self.subscription)

    def _on_progress(self, progress: Progress) -> None:
        cid = progress.command_id
        c = self.commands.get(cid)
        if c is not None:
            if c.last == progress:
                return  # the same change twice (two subscriptions for a moment)
            c.last = progress
            request_id, label = c.request_id, c.label
        elif cid in self.ended:
            request_id, label = self.ended[cid]
        else:  # a command a_co holds from before a_hi (re)started
            request_id, label = cid.removeprefix("cmd-"), cid
        self._report(request_id, ReportKind.PROGRESS, progress_text(label, progress))


__all__ = [
    "HumanInterface",
    "OpenCommand",
    "PeerAlive",
    "StopRequest",
    "progress_text",
    "sentence",
    "status_line",
]
