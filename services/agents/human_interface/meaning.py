"""From a parse tree of a_hi's grammar to an intent: the frame of the verb gives the task, and
each reference is resolved against the vocabulary (the things a_km knows, where they are).

Frames of grammar.lark (X the theme, Y the goal, Z the source; the task names and argument
orders are a_pl's, services/agents/planner/domain.py ``TASKS``):

==================================================  ===========================================
sentence                                            task
==================================================  ===========================================
pour X into Y, pour from X into Y, pour the         ``pour(X, Y)``
contents of X into Y, pour out X into Y, empty X
into Y, fill [up] Y from/with X
bring/fetch/get X [to me | here], take X out of Z,  ``bring(X)`` (to the table)
take out X, bring over/back X, I'd like X
bring/take X to Y, put/place/set/leave X on/in Y    ``place(X, Y)``
put X down, put down X                              ``place(X, table)`` (:data:`~.intents.SURFACE`)
put X back, put X away, return X, put X in the      ``return(X)`` (back in the cabinet)
cabinet, take X back, take away X
hand me X, give X to me, hand over X, can I have X  ``hand_over(X)``
stop [everything]                                   :class:`Stop`
what are you doing?, status                         :class:`StatusRequest`
==================================================  ===========================================

A place a_hi cannot see ("put the cup over there", "somewhere") raises :class:`Incomplete`,
asking where; in "bring me the cup over there" it says where the cup is, and is left out.

The frames of tasks.toml ("pick up THEME", "tidy THEME away", "find THEME", rules ``said_<n>``
of task_grammar.py) give their entry's task, each slot's reference an argument in the entry's
order; a slot left out or "it" with nothing named before gets the entry's question
(:meth:`Reader.said`).

A reference ("the small cup on the table", "the contents of the jar", "the jar's contents",
"the beans", "the jar's beans", "it", "the one in the cabinet") becomes one individual's O_RoCo
name: the things its noun names, narrowed by its adjectives and where it is said to be (in/on/
from Z, or an owner: "the cabinet's cup" is the cup in the cabinet). "it"/"that" is the last
object the same person named. More than one left raises :class:`Ambiguous` (a question), none
:class:`UnknownReference`; a missing argument :class:`Incomplete` (a question).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from lark import Token, Tree

from services.agents.human_interface.intents import (
    STORAGE,
    SURFACE,
    URGENT_PRIORITY,
    Ambiguous,
    Command,
    Incomplete,
    Intent,
    NotUnderstood,
    StatusRequest,
    Stop,
    UnknownReference,
    show,
)
from services.agents.human_interface.similarity import MARGIN, nearest
from services.agents.human_interface.task_grammar import SaidFrame, frame_node
from services.agents.human_interface.task_words import MISSING, ROLE_RULES, Frame, TaskSaying
from services.agents.human_interface.vocabulary import Thing, Vocabulary
from shared.fipa_codec.languages.l_hc import TaskAtom

Node = Tree[Token]


@dataclass
class Context:
    """What a reading is interpreted against: the ``vocabulary``; the ``last`` object the person
    named (for "it"); ``chosen``: references already settled by the person's answer to a
    question (first token index → O_RoCo name); ``among``: for a bare reply, the candidates of
    the question it answers; ``token_seconds``: DEADLINE values by token index; ``frames``: the
    frames of the task words by rule name (task_grammar.py)."""

    vocabulary: Vocabulary
    last: str | None = None
    chosen: dict[int, str] = field(default_factory=dict)
    among: tuple[str, ...] = ()
    token_seconds: dict[int, float] = field(default_factory=dict)
    frames: Mapping[str, SaidFrame] = field(default_factory=dict)


@dataclass(frozen=True)
class Reply:
    """A bare reference, the answer to a question: the individual it names, and the urgency
    or deadline said with it ("the small one, and make it quick"), which the command it
    completes takes."""

    name: str
    urgent: bool = False
    deadline_s: float | None = None


def _first_index(node: Node | Token) -> int:
    if isinstance(node, Token):
        return int(node.start_pos or 0)
    return min((int(t.start_pos or 0) for t in node.scan_values(lambda v: isinstance(v, Token))), default=0)


def _child(node: Node, name: str) -> Node | None:
    return next((c for c in node.children if isinstance(c, Tree) and c.data == name), None)


def _tokens(node: Node, kind: str) -> list[Token]:
    return [c for c in node.children if isinstance(c, Token) and c.type == kind]


def _dest(node: Node) -> Node | None:
    """The destination of a frame (``dest_goal``, ``dest_me``, ``dest_home``), or None."""
    return next((c for c in node.children if isinstance(c, Tree) and c.data.startswith("dest")), None)


def _has(node: Node, kind: str) -> bool:
    return bool(_tokens(node, kind))


def loc_count(tree: Node) -> int:
    """How many references in ``tree`` carry a location ("the cup on the table"): a reading
    with fewer is preferred (its prepositions are the verb's arguments)."""
    return sum(1 for _ in tree.find_data("loc"))


def loc_depth(tree: Node) -> int:
    """The sum of the first token indexes of the located references in ``tree``: among equal
    readings the one attaching a location to the later noun ("the bowl on the table" in "pour the
    jar into the bowl on the table") has the larger sum, and is preferred."""
    return sum(_first_index(loc) for loc in tree.find_data("loc"))


def _described(said: str, things: list[Thing]) -> list[str] | None:
    """Each of ``things`` by a describing word that no other of them has and its noun ("the
    blue bowl"), or None when one of them has no such word. ``said``: what the person said of
    them (its last word their noun, unless it was "one")."""
    out = []
    for t in things:
        own = sorted(a for a in t.adjectives if not all(a in o.adjectives for o in things))
        if not own:
            return None
        noun = said.split()[-1] if said not in ("one", "contents") else _kind(t.name)
        out.append(f"the {own[0]} {noun}")
    return out if len(set(out)) == len(out) else None


def _kind(name: str) -> str:
    """The noun an O_RoCo individual is named by: ``bowl_2`` → "bowl", ``tea_pot`` → "tea pot"."""
    return re.sub(r"_\d+$", "", name).replace("_", " ")


def _named(things: list[Thing]) -> list[str]:
    """Each of ``things`` by its name, with where it is when they are not all in one place."""
    wheres = {t.where() for t in things}
    if len(wheres) == 1:
        return [show(t.name) for t in things]
    return [show(t.name) + (f" ({t.where()})" if t.where() else "") for t in things]


def _meant(adjectives: list[str], thing: Thing) -> tuple[float, list[tuple[str, str]]]:
    """How near ``adjectives`` come to ``thing``'s (the least similarity of those it does not
    have to the nearest it has) and each read as that one; (0.0, []) when one has none near
    enough, or all are its own (similarity.py :func:`~.similarity.nearest`)."""
    pairs = [(a, nearest(a, thing.adjectives)) for a in adjectives if a not in thing.adjectives]
    found = [(a, hit) for a, hit in pairs if hit is not None]
    if not pairs or len(found) < len(pairs):
        return 0.0, []
    return min(hit[1] for _, hit in found), [(a, hit[0]) for a, hit in found]


def _or(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


class Reader:
    """Interprets one reading in a :class:`Context`."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.v = ctx.vocabulary
        self.took: list[tuple[str, str]] = []
        """Describing words read as ones a_km uses ("little" as "small"), said back."""
        self.by_content: set[str] = set()
        """The containers a reference named by what is in them ("the beans", "the contents
        of the jar"): moved into another container, that is a pour (:meth:`_moved`)."""

    # ---- references --------------------------------------------------------------------
    def ref(self, node: Node | None, place: str | None = None) -> str | None:
        """The O_RoCo name ``node`` (a theme/goal/source or a ref) refers to; None when it is
        missing ("it" with nothing named before). ``place``: it must be in/on that place."""
        if node is None:
            return None
        if node.data in ("theme", "goal", "source"):
            node = node.children[0]  # type: ignore[assignment]
        assert isinstance(node, Tree)
        at = _first_index(node)
        if at in self.ctx.chosen:
            return self.ctx.chosen[at]
        if node.data == "ref_list":
            raise NotUnderstood(
                "Please give me one object at a time, e.g. 'bring me the jar', then 'bring me the cup'."
            )
        if node.data == "plural":
            word = _tokens(node, "PLURAL")[0]
            raise NotUnderstood(
                f"I handle one object at a time, not '{word}': say e.g. 'bring me the {word.value[:-1]}'."
            )
        if node.data == "pronoun":
            return self.ctx.last
        if node.data == "contents":
            inner = next((c for c in node.children if isinstance(c, Tree) and c.data != "det"), None)
            if inner is not None:
                name = self.ref(inner, place)
                if name is not None:
                    self.by_content.add(name)
                return name
            contents = [t for t in self.v.things if t.content and t.place]
            return self._choose("contents", contents, at, [], None, place)
        adjectives = [
            str(t) for a in node.children if isinstance(a, Tree) and a.data == "adj" for t in a.children
        ]
        loc = _child(node, "loc")
        where = self._loc(loc) if loc is not None else None
        owner = _child(node, "owner")
        if owner is not None:  # "the jar's beans": the beans in the jar
            where = self.ref(owner)
        if node.data == "one":
            pool = [t for t in self.v.things if not t.content]
            if self.ctx.among:
                pool = [t for t in pool if t.name in self.ctx.among]
            return self._choose("one", pool, at, adjectives, where, place)
        noun = self._noun(node)
        things = self.v.named(tuple(noun.split()))
        if node.data == "np_of":  # "the jar of beans": the jar the beans are in
            held = _tokens(node, "NOUN")[1]
            holders = {t.place for t in self.v.named(tuple(str(held).split())) if t.content}
            things = [t for t in things if t.name in holders]
            noun = f"{noun} of {held}"
        return self._choose(noun, things, at, adjectives, where, place)

    def _noun(self, node: Node) -> str:
        """The noun of an ``np``, ``owner`` or ``compound`` node; a plural owner ("the jars'")
        as the singular the vocabulary knows."""
        noun = next((t for t in node.children if isinstance(t, Token) and t.type == "NOUN"), None)
        if noun is not None:
            return str(noun)
        plural = str(_tokens(node, "PLURAL")[0])
        return next((plural[:-k] for k in (1, 2) if (plural[:-k],) in self.v.nouns), plural)

    def _loc(self, loc: Node) -> str:
        inner = next(c for c in loc.children if isinstance(c, Tree))
        name = self.ref(inner)
        if name is None:
            raise Incomplete("Which place do you mean? Say e.g. 'the cup on the table'.", "place")
        return name

    def _choose(
        self,
        noun: str,
        things: list[Thing],
        at: int,
        adjectives: list[str],
        where: str | None,
        place: str | None,
    ) -> str:
        said = " ".join([*adjectives, noun]) if noun not in ("one", "contents") else "one"
        if noun == "contents":
            said = "contents"
        if not things:
            raise UnknownReference(f"I know of no {said}; I know {self.v.examples()}.")
        fitting = [t for t in things if set(adjectives) <= t.adjectives]
        fitting = fitting or self._by_meaning(adjectives, things)
        if not fitting:
            them = "; ".join(
                f"{show(t.name)} is {', '.join(sorted(t.adjectives)) or 'not described'}" for t in things
            )
            raise UnknownReference(f"I know of no {said}: {them}.")
        for required in (where, place):
            if required is None:
                continue
            located = [t for t in fitting if t.place == required]
            if not located:
                them = "; ".join(
                    f"{show(t.name)} is {t.where() or 'somewhere I do not know'}" for t in fitting
                )
                raise UnknownReference(f"I know of no {said} in or on {show(required)}: {them}.")
            fitting = located
        if len(fitting) > 1:
            raise Ambiguous(self._which(said, fitting), at, tuple(t.name for t in fitting))
        thing = fitting[0]
        if thing.content and thing.place:
            self.by_content.add(thing.place)
            return thing.place  # "the beans": the container they are in
        return thing.name

    def _by_meaning(self, adjectives: list[str], things: list[Thing]) -> list[Thing]:
        """The ``things`` the describing words ``adjectives`` mean when a_km describes none of them
        so (similarity.py): each word not among a thing's adjectives read as the nearest of them;
        the things whose words are all near enough and nearly as near as the nearest thing's (all
        of them: a question back), the words read said back (``took``). Empty when none is."""
        scored = [(score, t, read) for t in things for score, read in [_meant(adjectives, t)] if read]
        if not scored:
            return []
        best = max(s for s, _, _ in scored)
        chosen = [(t, read) for s, t, read in scored if s > best - MARGIN]
        if len(chosen) == 1:
            self.took.extend(chosen[0][1])
        return [t for t, _ in chosen]

    @staticmethod
    def _which(said: str, things: list[Thing]) -> str:
        """The question back for ``things`` that all fit what was ``said``, naming what tells
        them apart in the person's words: where each is, else its kind when each is of another
        ("the bowl, the cup or the jar?"), else a describing word only it has ("the blue bowl or
        the white bowl?"), else its name."""
        wheres = [t.where() for t in things]
        kinds = [_kind(t.name) for t in things]
        if all(wheres) and len(set(wheres)) == len(wheres):
            options = [f"the one {w}" for w in wheres]
        elif len(set(kinds)) == len(kinds):  # "that thing": the bowl, the cup or the jar?
            options = [f"the {k}" for k in kinds]
        else:
            options = _described(said, things) or _named(things)
        noun = "one" if said in ("one", "contents") else said
        return f"Which {noun}: {_or(options)}?"

    # ---- the sentence ------------------------------------------------------------------
    def sentence(self, tree: Node, priority: int) -> Intent | Reply:
        """The intent of the reading ``tree`` (a ``start``). ``priority`` > 0 (given with the
        input) wins over urgency words. Raises NotUnderstood and its subclasses."""
        urgent, deadline = False, None
        request: Node | None = None
        for c in tree.children:
            if isinstance(c, Tree) and c.data in ("pre", "post"):
                urgent = urgent or _has(c, "URGENT")
                for tok in _tokens(c, "DEADLINE"):
                    deadline = self.ctx.token_seconds.get(int(tok.start_pos or 0))
            elif isinstance(c, Tree):
                request = c
        assert request is not None
        if request.data == "stop":
            return Stop()
        if request.data == "status":
            return StatusRequest()
        if request.data == "reply":
            name = self.ref(request.children[0])  # type: ignore[arg-type]
            if name is None:
                raise Incomplete("Which object do you mean? Say e.g. 'the cup on the table'.", "object")
            return Reply(name, urgent, deadline)
        request = frame_node(request)
        said = self.ctx.frames.get(request.data)
        frame = _FRAMES.get(request.data)
        if said is not None:
            goal = self.said(request, said.saying, said.frame)
        elif frame is not None:
            goal = frame(self, request)
        else:  # pragma: no cover - every command rule has a frame
            raise NotUnderstood(f"I cannot do '{request.data}' yet.")
        if priority <= 0:
            priority = URGENT_PRIORITY if urgent else 0
        return Command(goal, priority, deadline, read_as=tuple(self.took))

    # ---- frames ------------------------------------------------------------------------
    def _need(self, name: str | None, question: str, missing: str) -> str:
        if name is None:
            raise Incomplete(question, missing)
        return name

    def pour(self, node: Node, verb: str = "pour") -> TaskAtom:
        source = _child(node, "source_pp")
        goal_pp = _child(node, "goal_pp")
        dst = self.ref(_child(goal_pp, "goal")) if goal_pp is not None else None
        src = self.ref(_child(source, "source")) if source is not None else self.ref(_child(node, "theme"))
        into = f" into {show(dst)}" if dst else ""
        src = self._need(
            src, f"Which object should I {verb}{into}? Say e.g. '{verb} the jar into the bowl'.", "object"
        )
        dst = self._need(
            dst,
            f"Into what should I {verb} {show(src)}? Say e.g. '{verb} {show(src)} into the bowl'.",
            "destination",
        )
        return TaskAtom("pour", (src, dst))

    def empty(self, node: Node) -> TaskAtom:
        return self.pour(node, "empty")

    def fill(self, node: Node) -> TaskAtom:
        dst = self._need(
            self.ref(_child(node, "goal")),
            "What should I fill? Say e.g. 'fill the bowl from the jar'.",
            "destination",
        )
        src = self._need(
            self.ref(_child(node, "theme")),
            f"What should I fill {show(dst)} from? Say e.g. 'fill {show(dst)} from the jar'.",
            "source",
        )
        return TaskAtom("pour", (src, dst))

    def _theme(self, node: Node, question: str) -> str:
        source = _child(node, "source_pp")
        place = self.ref(_child(source, "source")) if source is not None else None
        return self._need(self.ref(_child(node, "theme"), place), question, "object")

    def _moved(self, x: str, dest: Node | None, *, back: bool, default: str) -> TaskAtom:
        """Where ``x`` goes by ``dest``: to the person (bring), back (return), or onto a place.
        Raises :class:`Incomplete` for a place a_hi cannot see ("over there", "somewhere")."""
        if dest is None:
            return TaskAtom(default, (x,))
        if dest.data == "dest_home":
            return TaskAtom("return", (x,))
        if dest.data == "dest_me":
            return TaskAtom("hand_over", (x,)) if default == "hand_over" else TaskAtom("bring", (x,))
        if dest.data == "dest_vague":
            said = next(c for c in dest.children if isinstance(c, Token))
            verb = "bring" if default == "bring" else "put"
            raise Incomplete(
                f"Where should I {verb} {show(x)}? I cannot tell where '{said}' is; "
                f"say e.g. 'put {show(x)} on the table'.",
                "destination",
            )
        prep = next(c for c in dest.children if isinstance(c, Token))
        y = self._need(
            self.ref(_child(dest, "goal")),
            f"Where should I put {show(x)}? Say e.g. 'put {show(x)} on the table'.",
            "destination",
        )
        if y == STORAGE and (back or prep.type != "ON"):  # "… to the cupboard": into it, not onto it
            return TaskAtom("return", (x,))
        if x in self.by_content and prep.type == "IN" and y not in (SURFACE, STORAGE):
            return TaskAtom("pour", (x, y))  # "put the beans into the bowl": what is in x goes
        if y == "table" and default == "bring":
            return TaskAtom("bring", (x,))
        return TaskAtom("place", (x, y))

    def bring(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I bring? Say e.g. 'bring me the jar'.")
        dest = _dest(node)
        if dest is not None and dest.data == "dest_vague" and _has(node, "ME"):
            dest = None  # "bring me the cup over there": where the cup is, not where it goes
        return self._moved(x, dest, back=False, default="bring")

    def take(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I take? Say e.g. 'take the jar out of the cabinet'.")
        dest = _dest(node)
        return self._moved(x, dest, back=False, default="bring")

    def take_back(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I take back? Say e.g. 'take the jar back'.")
        dest = _dest(node)
        return self._moved(x, dest, back=True, default="return")

    def put_away(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I put away? Say e.g. 'put the cup away'.")
        return self._moved(x, _dest(node), back=True, default="return")

    def put(self, node: Node) -> TaskAtom:
        dest = _dest(node)
        y = None
        if dest is not None and dest.data == "dest_goal":
            try:
                y = self.ref(_child(dest, "goal"))
            except NotUnderstood:
                y = None
        on = f" on {show(y)}" if y else ""
        x = self._theme(node, f"Which object should I put{on}? Say e.g. 'put the cup on the table'.")
        if dest is None and _has(node, "DOWN"):  # "put the cup down": where things are set down
            return TaskAtom("place", (x, SURFACE))
        if dest is None:
            raise Incomplete(
                f"Where should I put {show(x)}? "
                f"Say e.g. 'put {show(x)} on the table', or 'put {show(x)} back'.",
                "destination",
            )
        return self._moved(x, dest, back=False, default="place")

    def put_back(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I put back? Say e.g. 'put the jar back'.")
        dest = _dest(node)
        return self._moved(x, dest, back=True, default="return")

    def ret(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I put back? Say e.g. 'return the cup'.")
        dest = _dest(node)
        return self._moved(x, dest, back=True, default="return")

    def give(self, node: Node) -> TaskAtom:
        x = self._theme(node, "What should I hand you? Say e.g. 'hand me the cup'.")
        return TaskAtom("hand_over", (x,))

    def want(self, node: Node) -> TaskAtom:
        """ "I would like the cup [on the table]": brought, as "bring me the cup" is."""
        x = self._theme(node, "What would you like? Say e.g. 'I would like the cup'.")
        return self._moved(x, _dest(node), back=_has(node, "BACK"), default="bring")

    def give_other(self, node: Node) -> TaskAtom:
        raise NotUnderstood("I can hand things only to you; say e.g. 'hand me the cup'.")

    # ---- frames of the task words --------------------------------------------------------
    def said(self, node: Node, saying: TaskSaying, frame: Frame) -> TaskAtom:
        """The task of a frame of the task words: each slot's reference resolved (in the order
        said), the arguments in the entry's order. Raises :class:`Incomplete` for a slot left
        out or naming nothing ("it" with nothing named before), asking the entry's question."""
        found: dict[str, str | None] = {}
        for slot in frame.slots:
            found[slot] = self.ref(_child(node, ROLE_RULES[slot]))
        for slot in saying.args:
            if found.get(slot) is None:
                raise Incomplete(self._question(saying, frame, slot, found), MISSING[slot])
        return TaskAtom(saying.task, tuple(str(found[s]) for s in saying.args))

    def _question(self, saying: TaskSaying, frame: Frame, slot: str, found: dict[str, str | None]) -> str:
        """The question for ``slot`` missing: the entry's ``ask`` (its other slots named), else
        the frame said with "what" ("Find what?"); then an example: the entry's, else the frame
        said with the things named and, for the missing slots, things the vocabulary holds."""
        known = {s: show(n) for s, n in found.items() if n is not None}
        asked = saying.question(slot)
        if asked is not None:
            question = asked.format_map({s: known.get(s, "something") for s in saying.args})
        else:
            words = frame.fill({s: known.get(s, "what") for s in frame.slots})
            question = words[:1].upper() + words[1:] + "?"
        example = saying.example
        if example is None:
            spare = iter(
                show(t.name)
                for t in sorted(self.v.things, key=lambda t: t.name)
                if not t.content and t.name not in found.values()
            )
            example = frame.fill({s: known.get(s) or next(spare, "the cup") for s in frame.slots})
        return f"{question} Say e.g. '{example}'."


_FRAMES: dict[str, Callable[[Reader, Node], TaskAtom]] = {
    "pour": Reader.pour,
    "empty": Reader.empty,
    "fill": Reader.fill,
    "bring": Reader.bring,
    "take": Reader.take,
    "take_back": Reader.take_back,
    "take_away": Reader.put_away,
    "put": Reader.put,
    "put_back": Reader.put_back,
    "put_away": Reader.put_away,
    "ret": Reader.ret,
    "give": Reader.give,
    "give_other": Reader.give_other,
    "want": Reader.want,
}
"""Command rule of grammar.lark → the frame that makes its task (the rules generated from the
task words are :attr:`Context.frames`)."""

__all__ = ["Context", "Reader", "Reply", "loc_count", "loc_depth"]
