"""a_hi's side of C7 (fipa-query in L_WM, a_hi the initiator, a_km the participant): the words
for things, and the person's questions about the kitchen.

Words (vocabulary.py): a fipa-query per sentence asks a_km for the vocabulary, which the
sentence waits for; when a_km is away or does not answer within the role's reply-by
(agent.py ``VOCABULARY_REPLY_BY_S``), it is read with the last one; when a_km's token appears,
a_hi asks at once, and the sentences waiting for an earlier a_km wait for that answer instead.

Questions (questions.py reads them, answers.py words the answers): each is one more fipa-query
(``query-ref`` of an L_WM ``SparqlQuery``), answered to the person with one ``answer`` report.
When a_km is away, refuses, fails or does not answer within :data:`QUESTION_REPLY_BY_S`, the
answer says a_hi cannot reach its knowledge (answers.py :data:`~.answers.NO_KNOWLEDGE`): a
question never leaves the person waiting. A question asked of an a_km that went away is asked
again of the one whose token appears. "What can you do?" is answered from a_hi's own task words,
without a_km.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from services.agents.human_interface.answers import NO_KNOWLEDGE, answer_text, question_query
from services.agents.human_interface.intents import WorldQuestion
from services.agents.human_interface.language import default_vocabulary
from services.agents.human_interface.task_grammar import Grammar
from services.agents.human_interface.vocabulary import VOCABULARY_QUERY, Vocabulary
from services.agents.human_interface.wording import dropped, reason_of
from services.runtime.agent import Agent, HumanInput, ReportKind
from services.runtime.roles import INITIATOR, Conversation, handles
from services.spec.names import C7, FIPA_QUERY
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_wm import Answer, SparqlQuery

KM = "a_km"
QUESTION_REPLY_BY_S = 5.0
"""How long a person's question waits for a_km's answer before a_hi says it cannot reach it."""


@dataclass
class HeldSentence:
    """A sentence waiting for a_km's vocabulary; ``ready`` once answered or given up, with the
    ``vocabulary`` to read it with (None: the last one); ``stopped``: a stop came after it, so
    it is dropped, not read."""

    event: HumanInput
    ready: bool = False
    vocabulary: Vocabulary | None = None
    stopped: bool = False


@dataclass(frozen=True)
class AskedQuestion:
    """A person's question put to a_km (the data of its C7 conversation): the person's
    ``request_id`` and the ``question``."""

    request_id: str
    question: WorldQuestion


def abilities(grammar: Grammar) -> str:
    """What a_hi answers "what can you do?" with: its verbs (grammar.lark's and the task words',
    :meth:`~.task_grammar.Grammar.verbs`) and the questions it answers."""
    return (
        f"You can tell me to {grammar.verbs()}; and ask me about the kitchen, e.g. "
        "'what is in the bowl?', 'where is the cup?', 'is the jar empty?', 'what did you see?'."
    )


class AskingKnowledge(Agent):
    """a_hi's conversations with a_km on C7 (see the module docstring); a_hi (agent.py) gives
    the sentences, their reading and its reports."""

    grammar: Grammar
    held: deque[HeldSentence]
    _vocabulary: Vocabulary | None

    def _understand(self, event: HumanInput, vocabulary: Vocabulary) -> None:  # pragma: no cover
        raise NotImplementedError

    def _report(self, request_id: str, kind: ReportKind, text: str) -> None:  # pragma: no cover
        raise NotImplementedError

    @property
    def vocabulary(self) -> Vocabulary:
        """The last vocabulary a_km gave; before its first answer, the files' (O_RoCo and the
        kitchen, read with rdflib at the first use: an idle a_hi does not load rdflib)."""
        if self._vocabulary is None:
            self._vocabulary = default_vocabulary()
        return self._vocabulary

    @vocabulary.setter
    def vocabulary(self, value: Vocabulary) -> None:
        self._vocabulary = value

    # ---- words -------------------------------------------------------------------------------
    def _ask_words(self, prefix: str, *waiting: HeldSentence) -> None:
        """Ask a_km for its vocabulary (C7, ``query-ref``) for the ``waiting`` sentences (the
        conversation's data; none for the question asked when a_km's token appears)."""
        self.roles.open(
            C7,
            FIPA_QUERY,
            SparqlQuery(VOCABULARY_QUERY),
            performative=Performative.QUERY_REF,
            conversation_id=self.sources.new_id(prefix),  # never one a_km has seen end
            data=list(waiting),
        )

    def peer_changed(self, peer: str, alive: bool) -> None:
        """a_km's token appeared (a_km started or restarted): ask for its vocabulary at once, and
        let the sentences still waiting for an earlier a_km wait for this answer instead; ask
        the person's open questions again."""
        if peer != KM or not alive:
            return
        waiting: list[HeldSentence] = []
        questions: list[AskedQuestion] = []
        for query in self.roles.conversations(C7, FIPA_QUERY):
            query.forget()  # asked of the a_km that went away, or before it was up
            if isinstance(query.data, AskedQuestion):
                questions.append(query.data)
            else:
                waiting += query.data  # the sentences it was asked for (see _ask_words)
        self._ask_words("words-", *waiting)
        for asked in questions:
            self._ask_world(asked.request_id, asked.question)

    def _read_held(self) -> None:
        """Read the waiting sentences, in order, as far as their vocabulary is there."""
        while self.held and self.held[0].ready:
            held = self.held.popleft()
            if held.stopped:
                self._report(held.event.request_id, ReportKind.NOT_UNDERSTOOD, dropped(held.event.text))
                continue
            self._understand(held.event, held.vocabulary or self.vocabulary)

    @handles(FIPA_QUERY, INITIATOR, Performative.INFORM_REF, Performative.INFORM, channel=C7)
    def _on_vocabulary(self, conv: Conversation) -> None:
        """a_km's answer: the vocabulary, the sentences waiting for it read; or a question's answer."""
        conv.forget()
        if isinstance(conv.data, AskedQuestion):
            self._answer_world(conv.data, conv.content)
            return
        if isinstance(conv.content, Answer) and conv.content.rows:
            self.vocabulary = Vocabulary.from_rows(conv.content.rows)
        if conv.data:
            for held in conv.data:
                held.ready, held.vocabulary = True, self.vocabulary
            self._read_held()

    @handles(FIPA_QUERY, INITIATOR, Performative.REFUSE, Performative.FAILURE, channel=C7)
    def _on_no_vocabulary(self, conv: Conversation) -> None:
        """Refused, failed, not understood or unanswered in time: read with the last vocabulary;
        a question: the person is told a_hi cannot reach its knowledge."""
        conv.forget()
        if isinstance(conv.data, AskedQuestion):
            self.log.warning("a_km did not answer a question (%s)", reason_of(conv))
            self._report(conv.data.request_id, ReportKind.ANSWER, NO_KNOWLEDGE)
            return
        self.log.warning("a_km gave no vocabulary (%s); reading with the last one", reason_of(conv))
        if conv.data:
            for held in conv.data:
                held.ready = True
            self._read_held()

    # ---- questions ---------------------------------------------------------------------------
    def _ask_world(self, request_id: str, question: WorldQuestion) -> None:
        """Answer ``question`` for the person's request ``request_id``: at once ("what can you
        do?", or a_km away), else when a_km answers the query-ref."""
        if question.kind == "abilities":
            self._report(request_id, ReportKind.ANSWER, abilities(self.grammar))
        elif KM not in self.peers:
            self._report(request_id, ReportKind.ANSWER, NO_KNOWLEDGE)
        else:
            self.roles.open(
                C7,
                FIPA_QUERY,
                SparqlQuery(question_query(question)),
                performative=Performative.QUERY_REF,
                conversation_id=self.sources.new_id(f"ask-{request_id}-"),
                data=AskedQuestion(request_id, question),
                reply_by_s=QUESTION_REPLY_BY_S,
            )

    def _answer_world(self, asked: AskedQuestion, content: object) -> None:
        """a_km's answer to a question: one sentence, its age on a_hi's clock (``Agent.sources``)."""
        if isinstance(content, Answer):
            text = answer_text(asked.question, content.rows, self.sources.time())
        else:
            text = NO_KNOWLEDGE
        self._report(asked.request_id, ReportKind.ANSWER, text)


__all__ = ["KM", "QUESTION_REPLY_BY_S", "AskedQuestion", "AskingKnowledge", "HeldSentence", "abilities"]
