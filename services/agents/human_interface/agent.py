"""a_hi — the human interface (paper §5.2; docs/agents.md, "a_hi"): takes sentences from a
person, tells them what happens.

Receptor ``roco/human/in`` (:class:`HumanInput`), effector ``roco/human/out``
(:class:`HumanReport`): every request of the person (command, stop, status) gets reports
under its own ``request_id`` and ends with one of a kind in FINAL_REPORTS
(services/runtime/human.py); their words are wording.py's. Towards a_co, on C2 in L_HC, a_hi
initiates a fipa-request per command (a stop sends ``cancel`` in every open one: the cancel
meta-protocol), one fipa-subscribe to the progress, which the role keeps open
(services/runtime/roles/subscriptions.py: while a_co does not agree, a new attempt, the interval
doubling from ``SUBSCRIBE_RETRY_S[0]`` to ``SUBSCRIBE_RETRY_S[1]``), and a fipa-query per status
request. Towards a_km, on C7 in L_WM (asking.py), a fipa-query per sentence asks for the
vocabulary (vocabulary.py), which the sentence waits for (at most ``VOCABULARY_REPLY_BY_S``),
and one per question about the kitchen (questions.py) for the answer.

Every line is first checked for a stop (stop.py), which is acted on at once, whatever it names;
the sentences still waiting are dropped. A line over ``MAX_LINE_CHARS`` that is no stop is
refused; the others are read in the order they came, by a thread of their own (reading.py), so
that a stop never waits for the parse of the line before it; a conversation per person keeps
what it named and a question asked back (language.py). Agents of other FIPA platforms ask on C8
(foreign.py).

Notices: a_hi is the participant of every notice protocol (one initiator ``inform`` that nothing
answers, by its state machine: services/spec/notices.py; ``roco-notify`` is one) on every channel
where the specification makes it so in L_HC (C8 today; a new agent with such a channel to a_hi
needs no edit here): each goes to the person as a ``notice`` report naming its sender, at most
``NOTICES_PER_S`` per sender a second (notices.py). Its text is what the content term says
(shared/fipa_codec/languages/told.py: a ``Notice``'s text, a term's own ``told()``, else its
string form).

Restarts (docs/recovery.md): a command's request is retransmitted until a_co agrees; the
fipa-request role keeps the open commands (``keep=CommandNote``), which a restarted a_hi takes
back (:meth:`HumanInterface.on_restored`), and the outcomes it told (``NOTE``:
services/runtime/person.py, asked on ``roco/human/outcomes``); open stops and status queries
are not kept.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import msgspec

from services.agents.human_interface.asking import KM, AskingKnowledge, HeldSentence
from services.agents.human_interface.foreign import ForeignRequests
from services.agents.human_interface.intents import Intent, Read
from services.agents.human_interface.language import (
    Command,
    Dialogue,
    NotUnderstood,
    StatusRequest,
    Stop,
    WorldQuestion,
    describe,
)
from services.agents.human_interface.notices import NoticeGate
from services.agents.human_interface.reading import LineReader, Reading
from services.agents.human_interface.stop import StopWords, command_openings
from services.agents.human_interface.task_grammar import Grammar, default_grammar, load_grammar
from services.agents.human_interface.vocabulary import Vocabulary
from services.agents.human_interface.wording import (
    NOTHING_TO_STOP,
    accepted,
    dropped,
    last_known,
    no_status,
    progress_text,
    reason_of,
    sentence,
    status_text,
    stopping,
    too_long,
)
from services.runtime.agent import (
    FINAL_REPORTS,
    FSM,
    MAX_LINE_CHARS,
    Behaviour,
    HumanInput,
    PersonFace,
    ReportKind,
    RequestKind,
    Told,
)
from services.runtime.roles import (
    EVERY_CHANNEL,
    EVERY_NOTICE,
    INITIATOR,
    PARTICIPANT,
    Conversation,
    RoleDecl,
    StandingSubscription,
    handles,
    initiator,
    participant,
)
from services.spec.names import C2, C7, C8, C9, FIPA_QUERY, FIPA_REQUEST, FIPA_SUBSCRIBE, L_HC, L_WM
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Notice,
    Progress,
    ProgressSubscription,
    Status,
    StatusQuery,
)
from shared.fipa_codec.languages.told import told

if TYPE_CHECKING:
    from services.runtime.agent import Transport
    from services.spec.model import SystemSpec

CO = "a_co"

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
VOCABULARY_REPLY_BY_S = 2.0
"""How long a sentence waits for a_km's vocabulary before it is read with the last one."""


@dataclass(frozen=True)
class ReadDone:
    """The reader (reading.py) is done with a line: act on the lines read, in order."""


class CommandNote(msgspec.Struct, kw_only=True):
    """What a_hi notes of a command's conversation (its :attr:`Conversation.data`, kept across
    a restart by the role: ``keep=CommandNote``): the person's request id, the command's label,
    whether a_co agreed."""

    request_id: str
    label: str
    agreed: bool = False


@dataclass
class OpenCommand:
    """A command sent to a_co and not yet ended. ``conversation_id`` is its C2
    conversation (a_co's ``command_id``), ``conversation`` that conversation, ``note`` its
    :class:`CommandNote` (the conversation's data); ``cancel`` the reply-with of an
    outstanding cancel; ``stoppers`` the stop requests waiting for its end."""

    conversation_id: str
    command: HumanCommand
    conversation: Conversation
    note: CommandNote
    cancel: str | None = None
    stoppers: list[str] = field(default_factory=list)
    last: Progress | None = None

    @property
    def request_id(self) -> str:
        return self.note.request_id

    @property
    def label(self) -> str:
        return self.note.label

    @property
    def agreed(self) -> bool:
        return self.note.agreed

    @agreed.setter
    def agreed(self, value: bool) -> None:
        self.note.agreed = value


@dataclass
class StopRequest:
    """A person's "stop": the commands whose end it awaits (conversation → label) and one
    line per command that has ended; ``failed`` when one could not be stopped."""

    request_id: str
    waiting: dict[str, str]
    lines: list[str] = field(default_factory=list)
    failed: bool = False


class HumanInterface(AskingKnowledge):
    """a_hi: sentences in, L_HC on C2 to a_co, readable reports out."""

    name = "a_hi"
    NOTE = Told
    progress: StandingSubscription
    """a_co's progress stream (services/runtime/roles/subscriptions.py), opened in :meth:`setup`."""
    ROLES: ClassVar[tuple[RoleDecl, ...]] = (
        # open commands are kept across a restart, each sent again (docs/recovery.md)
        initiator(C2, FIPA_REQUEST, L_HC, reply_by_s=AGREE_BY_S, retry_s=COMMAND_RETRY_S, keep=CommandNote),
        initiator(C2, FIPA_SUBSCRIBE, L_HC, reply_by_s=SUBSCRIBE_REPLY_BY_S, resubscribes=True),
        initiator(C2, FIPA_QUERY, L_HC, reply_by_s=STATUS_REPLY_BY_S),
        initiator(C7, FIPA_QUERY, L_WM, reply_by_s=VOCABULARY_REPLY_BY_S),
        initiator(C7, FIPA_SUBSCRIBE, L_WM, unused=True),  # changes of the scene: a_km serves them
        participant(C8, FIPA_REQUEST, L_HC),
        participant(C9, FIPA_REQUEST, L_HC),  # ROS 2 nodes through roco ros2: as C8
        # any agent the specification lets tell the person something (module docstring)
        participant(EVERY_CHANNEL, EVERY_NOTICE, L_HC),
    )

    def __init__(
        self, transport: Transport, spec: SystemSpec | None = None, *, tasks: Path | None = None
    ) -> None:
        """a_hi's memory (paper §3.2: the agent's internal memory), then the runtime's
        (:class:`~services.runtime.agent.Agent`), which builds the FSM and gives the kept
        commands back (:meth:`on_restored`), then what needs the runtime's log and clocks.
        ``tasks``: the task words file (default: tasks.toml beside this module, task_words.py),
        read and checked here, at start. Raises :class:`~.task_words.TaskWordsError` (a
        ValueError: services/runtime/main.py prints it as one line) when it is missing or
        malformed, or a frame collides."""
        self.grammar: Grammar = default_grammar() if tasks is None else load_grammar(tasks)
        """grammar.lark with the frames of the task words: what a person can say."""
        self.stop_words = StopWords(command_openings(self.grammar))
        """The matcher every line goes through first (stop.py)."""
        self.commands: dict[str, OpenCommand] = {}  # conversation-id → open command
        self.asked: dict[str, RequestKind] = {}  # person's request id → what it was, until its final report
        self.stops: dict[str, StopRequest] = {}  # request_id → stop request
        self.read_as: dict[str, str] = {}  # request_id → its typos corrected, said in its first report
        self._vocabulary: Vocabulary | None = None  # the last vocabulary a_km gave (None: none yet)
        self.dialogues: dict[str, Dialogue] = {}  # person → conversation
        self.held: deque[HeldSentence] = deque()  # sentences waiting for the vocabulary, in order
        self.reading: deque[Reading] = deque()  # sentences given to the reader, in order
        self.reader = LineReader(self.grammar, lambda: self.post(ReadDone()))
        super().__init__(transport, spec)
        self.foreign = ForeignRequests(self.log, self.sources.new_id)  # agents of other platforms (C8)
        self.notices = NoticeGate(self.log, self.sources.monotonic)  # notices passed on, per sender

    def build_fsm(self) -> FSM:
        what = "turn sentences into requests, cancels and queries to a_co; "
        what += "report a_co's answers and progress to the person"
        return FSM([Behaviour("interact", self._interact, terminal=lambda: False, doc=what)])

    def setup(self) -> None:
        self.person = PersonFace(self, self.note)  # the outcomes it told, kept across a restart
        self.person.open()
        # opened when a_co's liveliness token is seen: it never waits on an a_co not there yet
        self.progress = self.roles.subscribe(
            C2,
            FIPA_SUBSCRIBE,
            ProgressSubscription(),
            conversation_id=SUBSCRIPTION,
            reply_by_s=SUBSCRIBE_REPLY_BY_S,
            retry_s=SUBSCRIBE_RETRY_S,
        )
        self.reader.start()  # loads the word-similarity model meanwhile (reading.py)

    # ---- restarts ----------------------------------------------------------------------
    def on_restored(self, conversation: Conversation) -> None:
        """An open command of a previous a_hi (its role keeps them): the runtime sends its
        request again, agreed or not, and a_co answers a repeated request as it answered it
        (its agree, and its outcome when the command ended while this a_hi was down, which
        would otherwise be lost). Raises TypeError for a conversation that is no command."""
        note = conversation.data
        if not isinstance(note, CommandNote):
            raise TypeError(f"conversation {conversation.conversation_id} has no note of a command")
        command = conversation.opening_content(HumanCommand)
        cid = conversation.conversation_id
        self.commands[cid] = OpenCommand(cid, command, conversation, note)

    # ---- the behaviour -----------------------------------------------------------------
    def _interact(self) -> None:
        while self.r:
            event = self.r.popleft()
            if isinstance(event, HumanInput):
                self._on_input(event)
            elif isinstance(event, ReadDone):
                self._act_on_read()
        self.handle_received()

    def _report(self, request_id: str, kind: ReportKind, text: str) -> None:
        # the first report of a request read with typos corrected says so ("I read 'doimg' as 'doing'.")
        text = " ".join(filter(None, (self.read_as.pop(request_id, ""), text)))
        self.log.info("to person [%s] %s: %s", request_id, kind.value, text)
        request = self.asked.pop(request_id, None) if kind in FINAL_REPORTS else self.asked.get(request_id)
        self.foreign.answer(self.person.tell(request_id, kind, text, request=request))

    # ---- notices (every notice protocol, participant, on every channel that gives a_hi one) ----
    @handles(EVERY_NOTICE, PARTICIPANT, Performative.INFORM)
    def _on_notice(self, conv: Conversation) -> None:
        """An agent tells the person something: a ``notice`` report with its name and what the
        content says (told.py: an L_HC ``Notice``'s text, with its severity and the things it
        is about; any other term's ``told()``, else its string form), unless it sent more
        than the gate passes this second (counted: ``notices_dropped``). A content that does
        not decode as its channel's ``contents`` allow is answered ``not-understood`` by the
        runtime; a notice without content, or whose term's ``told()`` fails, is logged and
        counted (``notices_unreadable``): a notice has no answer."""
        term = conv.content
        try:
            text = told(term) if term is not None else ""
        except Exception as exc:  # a term's own told() is the sender's code: any error of it
            text, why = "", f"{type(term).__name__}.told() failed: {exc}"
        else:
            why = "no content"
        if not text:
            self.counters["notices_unreadable"] += 1
            self.log.warning("a notice from %s says nothing to the person: %s", conv.peer, why)
            return
        if not self.notices.admit(conv.peer):
            self.counters["notices_dropped"] += 1
            return
        self.counters["notices"] += 1
        severity, about = (term.severity.value, term.about) if isinstance(term, Notice) else ("", ())
        self.log.info("to person: notice from %s (%s): %s", conv.peer, severity or "-", text)
        self.person.notice(conv.peer, text, severity=severity, about=about)

    # ---- from agents of other platforms (C8, fipa-request, participant: foreign.py) ---------
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST, channel=C8)
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST, channel=C9)
    def _on_foreign_request(self, conv: Conversation) -> None:
        """A foreign agent's sentence: read as a person's, its reports answer the request."""
        self._on_input(self.foreign.take(conv))

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.CANCEL, channel=C8)
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.CANCEL, channel=C9)
    def _on_foreign_cancel(self, conv: Conversation) -> None:
        """A foreign agent cancels its request (FIPA SC00026 §2): its sentence, if not yet
        acted on, is dropped, and its command, if running, is stopped as by a person's stop;
        foreign.py answers the cancel once that is settled."""
        request_id = self.foreign.cancelling(conv)
        if request_id is not None and not self._stop_request(request_id):
            self.foreign.nothing_to_cancel(request_id)

    def _stop_request(self, request_id: str) -> bool:
        """Drop the sentence of request ``request_id`` if it is not yet acted on, or cancel its
        command if one runs; whether anything of it was under way."""
        lines: list[HeldSentence | Reading] = [h for h in self.held if h.event.request_id == request_id]
        lines += [r for r in self.reading if r.event.request_id == request_id]
        for line in lines:
            line.stopped = True
        commands = [c for c in self.commands.values() if c.request_id == request_id]
        for c in commands:
            self._cancel_command(c, "as asked")
        return bool(lines or commands)

    # ---- from the person ---------------------------------------------------------------
    def _on_input(self, event: HumanInput) -> None:
        """A line: first checked for a stop (stop.py), which is acted on at once (it needs no
        words for things; the sentences still waiting are dropped); a line over
        ``MAX_LINE_CHARS`` is refused; any other is read at once when a_km is away, else after
        a_km's vocabulary."""
        stop = self.stop_words.match(event.text)
        if stop is not None:
            for held in self.held:
                held.stopped = True  # reported when its query ends (the query runs its course)
            for reading in self.reading:
                reading.stopped = True  # reported when the reader is done with it
            dialogue = self.dialogues.get(event.person)
            if dialogue is not None:
                dialogue.pending = None  # a question asked back is dropped, as by any sentence
            self.asked[event.request_id] = RequestKind.STOP
            self._stop_commands(event.request_id, stop.names)
            return
        if len(event.text) > MAX_LINE_CHARS:
            self._report(event.request_id, ReportKind.NOT_UNDERSTOOD, too_long(len(event.text)))
            return
        if KM not in self.peers:
            if not self.held:
                self._understand(event, self.vocabulary)
                return
            self.held.append(HeldSentence(event, ready=True))  # after those still waiting
            return
        held = HeldSentence(event)
        self.held.append(held)
        self._ask_words(f"words-{event.request_id}-", held)

    def _understand(self, event: HumanInput, vocabulary: Vocabulary) -> None:
        """Give ``event``'s line to the reader (reading.py); it is acted on, in order, once read."""
        reading = Reading(event, self.dialogues.setdefault(event.person, Dialogue()))
        self.reading.append(reading)
        self.reader.read(reading, vocabulary)

    def _act_on_read(self) -> None:
        """Act on the lines the reader is done with, in the order they came; a line a stop came
        after is dropped, with its question asked back, if any."""
        while self.reading and self.reading[0].done:
            reading = self.reading.popleft()
            event, outcome = reading.event, reading.outcome
            if isinstance(outcome, Read) and outcome.read_as:
                self.read_as[event.request_id] = outcome.said
            if reading.stopped:
                reading.dialogue.pending = None
                self._report(event.request_id, ReportKind.NOT_UNDERSTOOD, dropped(event.text))
            elif isinstance(outcome, NotUnderstood):
                self._report(event.request_id, ReportKind.NOT_UNDERSTOOD, str(outcome))
            elif outcome is not None:
                self._act(event, outcome)

    def _act(self, event: HumanInput, outcome: Intent) -> None:
        """Act on the intent a line was read as."""
        if isinstance(outcome, Command):
            self.asked[event.request_id] = RequestKind.COMMAND
            self._command(event, outcome)
        elif isinstance(outcome, Stop):
            self.asked[event.request_id] = RequestKind.STOP
            self._stop_commands(event.request_id)
        elif isinstance(outcome, StatusRequest):
            self.asked[event.request_id] = RequestKind.STATUS
            self._ask_status(event.request_id)
        elif isinstance(outcome, WorldQuestion):
            self.asked[event.request_id] = RequestKind.QUESTION
            self._ask_world(event.request_id, outcome)

    def _command(self, event: HumanInput, intent: Command) -> None:
        if intent.instead_of is not None:  # "no, the other one": the command it replaces stops
            for c in list(self.commands.values()):
                if c.command.goal == intent.instead_of:
                    self._cancel_command(c, "you asked for the other one")
        command = HumanCommand(
            text=event.text, goal=intent.goal, priority=intent.priority, deadline_s=intent.deadline_s
        )
        note = CommandNote(request_id=event.request_id, label=describe(intent.goal, self.grammar.words))
        conv = self.roles.open(
            C2,
            FIPA_REQUEST,
            command,
            conversation_id=self.roles.free_id(f"cmd-{event.request_id}", taken=self.commands),
            data=note,
        )
        cid = conv.conversation_id
        if CO not in self.peers:
            self.log.warning("a_co is not known to be alive; %s may wait %.0f s", cid, AGREE_BY_S)
        self.commands[cid] = OpenCommand(cid, command, conv, note)

    def _stop_commands(self, request_id: str, named: str = "") -> None:
        """Cancel every open command for stop request ``request_id``; ``named``: what the
        person's stop named ("pouring"), said back, as a_hi stops all of them."""
        if not self.commands:
            self._report(request_id, ReportKind.STOPPED, NOTHING_TO_STOP)
            return
        stop = StopRequest(request_id, {c.conversation_id: c.label for c in self.commands.values()})
        self.stops[request_id] = stop
        for c in self.commands.values():
            c.stoppers.append(request_id)
            self._cancel_command(c, "as you asked")
        self._report(request_id, ReportKind.PROGRESS, stopping(list(stop.waiting.values()), named))

    def _cancel_command(self, c: OpenCommand, why: str) -> None:
        """Send a_co the cancel of command ``c`` and tell its person it is stopping ``why``,
        unless a cancel is already on its way (its answer ends the command)."""
        if c.cancel is None:
            c.cancel = c.conversation.cancel(c.command, reply_by_s=CANCEL_REPLY_BY_S)
            self._report(c.request_id, ReportKind.PROGRESS, f"{c.label}: stopping, {why}")

    def _ask_status(self, request_id: str) -> None:
        self.roles.open(
            C2,
            FIPA_QUERY,
            StatusQuery(),
            performative=Performative.QUERY_REF,
            conversation_id=self.roles.free_id(f"status-{request_id}", taken=self.commands),
            data=request_id,  # the person's request it answers
        )

    # ---- a_co's answers to commands (fipa-request, initiator) ---------------------------
    def _open_command(self, conv: Conversation) -> OpenCommand | None:
        c = self.commands.get(conv.conversation_id)
        if c is None and conv.last is not None:
            self.log.debug(
                "late %s in ended conversation %s", conv.last.performative.value, conv.conversation_id
            )
        return c

    @handles(FIPA_REQUEST, INITIATOR, Performative.AGREE)
    def _on_agreed(self, conv: Conversation) -> None:
        c = self._open_command(conv)
        if c is None or conv.answers_cancel:
            return  # an agree crossing a cancel is not part of the cancel meta-protocol
        if c.agreed:  # a_co's agree again, to the request a restarted a_hi sent again: said already
            conv.await_reply(COMMAND_REPLY_BY_S)
            return
        c.agreed = True
        conv.await_reply(COMMAND_REPLY_BY_S)  # the agree answers the request; the outcome may take long
        self._report(c.request_id, ReportKind.ACCEPTED, accepted(c.label, c.command))

    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_command_done(self, conv: Conversation) -> None:
        c = self._open_command(conv)
        if c is None:
            return
        outcome = conv.content if isinstance(conv.content, CommandOutcome) else None
        if conv.answers_cancel:
            c.cancel = None
            if outcome is not None and outcome.succeeded:  # it finished before it could stop
                self._end(c, ReportKind.SUCCEEDED, sentence(c.label, "succeeded", outcome.detail))
            else:
                self._end(
                    c,
                    ReportKind.STOPPED,
                    sentence(c.label, "stopped", outcome.detail if outcome else ""),
                )
        elif outcome is None or outcome.succeeded:
            self._end(
                c,
                ReportKind.SUCCEEDED,
                sentence(c.label, "succeeded", outcome.detail if outcome else ""),
            )
        elif self._stopping(c):
            self._end(c, ReportKind.STOPPED, sentence(c.label, "stopped", outcome.detail))
        else:
            self._end(c, ReportKind.FAILED, sentence(c.label, "failed", outcome.detail))

    @handles(FIPA_REQUEST, INITIATOR, Performative.FAILURE)
    def _on_command_failed(self, conv: Conversation) -> None:
        """A failure, or no answer by the reply-by deadline."""
        c = self._open_command(conv)
        if c is None:
            return
        if conv.answers_cancel:
            self._not_stopped(c, conv)
        elif conv.timed_out:
            waited = COMMAND_REPLY_BY_S if c.agreed else AGREE_BY_S
            reason = f"a_co did not {'finish' if c.agreed else 'answer'} within {waited:.0f} s"
            self._end(c, ReportKind.FAILED, sentence(c.label, "failed", reason))
        elif self._stopping(c) and reason_of(conv).lower().startswith("stopped"):
            self._end(c, ReportKind.STOPPED, sentence(c.label, "stopped", reason_of(conv)))
        else:
            self._end(c, ReportKind.FAILED, sentence(c.label, "failed", reason_of(conv)))

    @handles(FIPA_REQUEST, INITIATOR, Performative.REFUSE)
    def _on_command_refused(self, conv: Conversation) -> None:
        c = self._open_command(conv)
        if c is not None:
            self._end(c, ReportKind.FAILED, sentence(c.label, "refused", reason_of(conv)))

    @handles(FIPA_REQUEST, INITIATOR, Performative.NOT_UNDERSTOOD)
    def _on_command_not_understood(self, conv: Conversation) -> None:
        c = self._open_command(conv)
        if c is None:
            return
        if conv.answers_cancel:
            self._not_stopped(c, conv)
        else:  # a_co did not understand the command, or a_hi could not read a_co's answer
            who = (
                "a_hi could not read a_co's answer"
                if conv.unreadable
                else "a_co did not understand the command"
            )
            self._end(c, ReportKind.FAILED, f"{c.label}: {who}; {reason_of(conv)}")

    @staticmethod
    def _stopping(c: OpenCommand) -> bool:
        return c.cancel is not None or bool(c.stoppers)

    def _not_stopped(self, c: OpenCommand, conv: Conversation) -> None:
        """The cancel failed, was not understood, or had no answer in time: it goes on."""
        c.cancel = None
        reason = reason_of(conv)
        if conv.timed_out:
            reason = f"a_co did not confirm the stop within {CANCEL_REPLY_BY_S:.0f} s"
        line = sentence(c.label, "could not be stopped", reason)
        self._report(c.request_id, ReportKind.PROGRESS, line)
        self._tell_stoppers(c, line, ok=False)

    def _end(self, c: OpenCommand, kind: ReportKind, text: str) -> None:
        """Command ``c`` has ended: the final report, and every stop request waiting for it."""
        self._report(c.request_id, kind, text)
        del self.commands[c.conversation_id]
        c.conversation.forget(remember=True)  # its note names the person's request of late progress
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

    # ---- a_co's answers to status queries (fipa-query, initiator) ------------------------
    @handles(FIPA_QUERY, INITIATOR, Performative.INFORM_REF, Performative.INFORM, channel=C2)
    def _on_status(self, conv: Conversation) -> None:
        self._status_answer(conv, True)

    @handles(FIPA_QUERY, INITIATOR, Performative.REFUSE, Performative.FAILURE, channel=C2)
    def _on_no_status(self, conv: Conversation) -> None:
        """Refused, failed, not understood, or unanswered by the reply-by deadline."""
        self._status_answer(conv, False)

    def _status_answer(self, conv: Conversation, answered: bool) -> None:
        request_id: str = conv.data  # (see _ask_status)
        conv.forget()  # (what a_co still sends in it is dropped by the role)
        labels = {c.conversation_id: c.label for c in self.commands.values()}
        status = conv.content
        if answered and isinstance(status, Status):
            self._report(request_id, ReportKind.STATUS, status_text(status, labels))
            return
        reason = "its answer held no status" if answered else reason_of(conv)
        known = [last_known(c.label, c.last, c.agreed) for c in self.commands.values()]
        self._report(request_id, ReportKind.STATUS, no_status(reason, known))

    # ---- the progress subscription (fipa-subscribe, initiator; kept open by the role) ----
    @handles(FIPA_SUBSCRIBE, INITIATOR, Performative.INFORM)
    def _on_progress_inform(self, conv: Conversation) -> None:
        if isinstance(conv.content, Progress):
            self._on_progress(conv.content)

    def _on_progress(self, progress: Progress) -> None:
        cid = progress.command_id
        c = self.commands.get(cid)
        if c is not None:
            if c.last == progress:
                return  # the same change twice (two subscriptions for a moment)
            c.last = progress
            request_id, label = c.request_id, c.label
        elif (ended := self.roles.ended(cid)) is not None:  # a command that ended (its CommandNote)
            request_id, label = ended.request_id, ended.label
        else:  # a command a_co holds from before a_hi (re)started
            request_id, label = cid.removeprefix("cmd-"), cid
        self._report(request_id, ReportKind.PROGRESS, progress_text(label, progress))


__all__ = ["HumanInterface", "OpenCommand", "StopRequest"]
