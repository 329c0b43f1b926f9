"""The corpus: sentences a person in the kitchen says, each with what a_hi must make of it — an
L_HC command (or stop, or status request), a question back, or a refusal that names the word or
the missing part. test_corpus.py runs every sentence. It covers every task a_pl accepts, those
whose frames are grammar.lark's and those whose frames are tasks.toml's (fetch, the tidy frames of
return, localise).

- :data:`PARAPHRASES`: different wordings of the tasks, against the kitchen as O_RoCo states it
  (one jar, bowl, cup, table, cabinet);
- :data:`REFERENCES`: ambiguous, unknown and located references, against the kitchen with a
  second cup standing on the table (:data:`SECOND_CUP`, a fact stated as a_km would hold it);
- :data:`REFUSALS`: sentences a_hi must not turn into a command;
- :data:`PHRASAL`, :data:`POSSESSIVES`, :data:`POLITE`, :data:`WISHES`, :data:`TAG_QUESTIONS`,
  :data:`DEADLINES`, :data:`LOCALISE`: everyday wordings beyond the first ones, each group
  against the one-cup kitchen;
- :data:`BAD_INPUT`: a negative or zero deadline and control characters refused, vague places
  asked back.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Do:
    """A command: its task, arguments, and the priority and deadline the words give."""

    task: str
    args: tuple[str, ...]
    priority: int = 0
    deadline_s: float | None = None

    def __init__(self, task: str, *args: str, priority: int = 0, deadline_s: float | None = None) -> None:
        object.__setattr__(self, "task", task)
        object.__setattr__(self, "args", args)
        object.__setattr__(self, "priority", priority)
        object.__setattr__(self, "deadline_s", deadline_s)


@dataclass(frozen=True)
class Ask:
    """A question back: ``kind`` "which" (ambiguous) or "missing" (incomplete), and words it must hold."""

    kind: str
    says: str


@dataclass(frozen=True)
class Refuse:
    """A refusal: one line holding ``says`` (the word not understood, or what is wrong)."""

    says: str


@dataclass(frozen=True)
class Question:
    """A question about the kitchen (questions.py): its kind and the thing it asks about."""

    kind: str
    thing: str | None = None


STOP = "stop"
STATUS = "status"
Expected = Do | Ask | Refuse | Question | str

URGENT = 5

SECOND_CUP = """@prefix roco: <https://w3id.org/roco/O_RoCo#> .
roco:cup_2 a roco:Cup ; roco:on roco:table ; roco:adjective "blue" , "large" .
"""
"""A second cup, on the table: with it "the cup" is ambiguous."""

PARAPHRASES: tuple[tuple[str, Expected], ...] = (
    ("pour the jar into the bowl", Do("pour", "jar", "bowl")),
    ("pour the contents of the jar into the bowl", Do("pour", "jar", "bowl")),
    ("Could you pour the contents of the jar into the bowl?", Do("pour", "jar", "bowl")),
    ("please pour what is in the jar into the bowl", Do("pour", "jar", "bowl")),
    ("pour the beans into the bowl", Do("pour", "jar", "bowl")),
    ("pour the beans from the jar into the bowl", Do("pour", "jar", "bowl")),
    ("pour from the jar into the bowl", Do("pour", "jar", "bowl")),
    ("pour into the bowl from the jar", Do("pour", "jar", "bowl")),
    ("pour the jar out into the bowl", Do("pour", "jar", "bowl")),
    ("tip the jar into the bowl", Do("pour", "jar", "bowl")),
    ("decant the glass jar into the salad bowl", Do("pour", "jar", "bowl")),
    ("transfer the balls into the dish", Do("pour", "jar", "bowl")),
    ("empty the jar into the bowl", Do("pour", "jar", "bowl")),
    ("empty out the jar into the bowl", Do("pour", "jar", "bowl")),
    ("empty the glass jar into the white bowl", Do("pour", "jar", "bowl")),
    ("fill the bowl from the jar", Do("pour", "jar", "bowl")),
    ("fill the bowl with the beans", Do("pour", "jar", "bowl")),
    ("fill the bowl up with the contents of the jar", Do("pour", "jar", "bowl")),
    ("could you fill the dish from the glass jar, please?", Do("pour", "jar", "bowl")),
    ("refill the bowl from the jar", Do("pour", "jar", "bowl")),
    ("I'd like you to pour the jar into the bowl, thanks", Do("pour", "jar", "bowl")),
    ("would you be so kind as to pour the jar into the bowl", Do("pour", "jar", "bowl")),
    ("robot, pour the jar into the basin", Do("pour", "jar", "bowl")),
    ("pour the big jar into the large bowl", Do("pour", "jar", "bowl")),
    ("pour the marbles in the bowl", Do("pour", "jar", "bowl")),
    ("bring me the cup", Do("bring", "cup")),
    ("bring the cup to the table", Do("bring", "cup")),
    ("bring the mug here", Do("bring", "cup")),
    ("bring the cup over here", Do("bring", "cup")),
    ("bring the bowl over", Do("bring", "bowl")),
    ("fetch the cup", Do("bring", "cup")),
    ("fetch me the coffee mug", Do("bring", "cup")),
    ("get me the jar", Do("bring", "jar")),
    ("get the jar for me", Do("bring", "jar")),
    ("grab the bowl", Ask("which", "Should I bring you the bowl?")),  # bring it, or pick it up?
    ("grab me the bowl", Do("bring", "bowl")),
    ("carry the bowl to the table", Do("bring", "bowl")),
    ("take the jar out of the cabinet", Do("bring", "jar")),
    ("take the jar from the cupboard", Do("bring", "jar")),
    ("take the small cup out of the kitchen cabinet", Do("bring", "cup")),
    ("get the bowl out of the cabinet", Do("bring", "bowl")),
    ("could you bring me the teacup?", Do("bring", "cup")),
    ("can you get me the glass jar please", Do("bring", "jar")),
    ("go and fetch the bowl", Do("bring", "bowl")),
    ("bring me the cup that is in the cabinet", Do("bring", "cup")),
    ("bring me the cup from the cabinet", Do("bring", "cup")),
    ("remove the jar from the cabinet", Do("bring", "jar")),
    ("hey velma, bring me the jar", Do("bring", "jar")),
    ("bring the bowl onto the table", Do("bring", "bowl")),
    ("put the cup on the table", Do("place", "cup", "table")),
    ("place the cup on the table", Do("place", "cup", "table")),
    ("set the cup on the kitchen table", Do("place", "cup", "table")),
    ("leave the mug on the table", Do("place", "cup", "table")),
    ("put the jar onto the table", Do("place", "jar", "table")),
    ("stand the jar on the wooden table", Do("place", "jar", "table")),
    ("put the bowl down on the table", Do("place", "bowl", "table")),
    ("move the bowl to the table", Do("place", "bowl", "table")),
    ("put down the jar on the table", Do("place", "jar", "table")),
    ("put the jar back on the table", Do("place", "jar", "table")),
    ("take the cup to the table", Do("bring", "cup")),
    ("lay the bowl on the table", Do("place", "bowl", "table")),
    ("put the little white cup on the dining table", Do("place", "cup", "table")),
    ("could you place the jar on top of the table?", Do("place", "jar", "table")),
    ("put the jar back", Do("return", "jar")),
    ("put the jar back in the cabinet", Do("return", "jar")),
    ("put back the jar", Do("return", "jar")),
    ("put the jar in the cabinet", Do("return", "jar")),
    ("put the jar into the cupboard", Do("return", "jar")),
    ("put the cup away", Do("return", "cup")),
    ("put away the cup", Do("return", "cup")),
    ("return the cup", Do("return", "cup")),
    ("return the cup to the cabinet", Do("return", "cup")),
    ("store the bowl", Do("return", "bowl")),
    ("stow the bowl in the cabinet", Do("return", "bowl")),
    ("take the jar back", Do("return", "jar")),
    ("take the cup away", Do("return", "cup")),
    ("tidy the cup away", Do("return", "cup")),
    ("tidy away the bowl", Do("return", "bowl")),
    ("put the jar where it belongs", Do("return", "jar")),
    ("put the cup back where it was", Do("return", "cup")),
    ("return the mug to its place", Do("return", "cup")),
    ("please put the bowl back in the shelf", Do("return", "bowl")),
    ("pick up the cup", Do("fetch", "cup")),
    ("pick the cup up", Do("fetch", "cup")),
    ("hold the jar", Do("fetch", "jar")),
    ("grasp the bowl", Do("fetch", "bowl")),
    ("lift the glass jar", Do("fetch", "jar")),
    ("hand me the cup", Do("hand_over", "cup")),
    ("give me the jar", Do("hand_over", "jar")),
    ("pass me the bowl", Do("hand_over", "bowl")),
    ("hand over the bowl", Do("hand_over", "bowl")),
    ("give the cup to me", Do("hand_over", "cup")),
    ("hand the mug over", Do("hand_over", "cup")),
    ("hand the jar over to me", Do("hand_over", "jar")),
    ("could you give me the coffee cup?", Do("hand_over", "cup")),
    ("please pass me the salad bowl, thank you", Do("hand_over", "bowl")),
    ("find the jar", Do("localise", "jar")),
    ("look for the cup", Do("localise", "cup")),
    ("where is the bowl?", Question("where", "bowl")),
    ("locate the jar", Do("localise", "jar")),
    ("could you find the glass jar, please?", Do("localise", "jar")),
    ("please look for the coffee mug", Do("localise", "cup")),
    ("robot, where is the salad bowl?", Question("where", "bowl")),
    ("search for the table", Do("localise", "table")),
    ("look where the cup is", Do("localise", "cup")),
    ("show me where the bowl is", Do("localise", "bowl")),
    ("find the beans", Do("localise", "jar")),
    ("where is the jar in the cabinet", Question("where", "jar")),
    ("stop", STOP),
    ("Stop everything!", STOP),
    ("please stop now", STOP),
    ("cancel", STOP),
    ("stop it", STOP),
    ("abort all tasks", STOP),
    ("halt", STOP),
    ("stop whatever you are doing", STOP),
    ("stop the pouring", STOP),
    ("stop pouring the jar", STOP),
    ("cancel the pour, please", STOP),
    ("what are you doing?", STATUS),
    ("Status", STATUS),
    ("What's going on?", STATUS),
    ("robot, what are you doing now?", STATUS),
    ("how is it going?", STATUS),
    ("are you busy?", STATUS),
    ("give me a status report", STATUS),
    # urgency and deadlines
    ("urgently bring me the cup", Do("bring", "cup", priority=URGENT)),
    ("bring me the cup right away", Do("bring", "cup", priority=URGENT)),
    ("quickly, hand me the jar", Do("hand_over", "jar", priority=URGENT)),
    ("pour the jar into the bowl as soon as possible", Do("pour", "jar", "bowl", priority=URGENT)),
    ("pour the jar into the bowl within 30 seconds", Do("pour", "jar", "bowl", deadline_s=30.0)),
    ("within 2 minutes, put the cup on the table", Do("place", "cup", "table", deadline_s=120.0)),
    ("fill the bowl from the jar within the next ten seconds", Do("pour", "jar", "bowl", deadline_s=10.0)),
    ("put the jar back within half an hour", Do("return", "jar", deadline_s=1800.0)),
    ("bring me the mug right away, within 45 seconds", Do("bring", "cup", priority=URGENT, deadline_s=45.0)),
    ("immediately put the bowl away please", Do("return", "bowl", priority=URGENT)),
    ("quickly, where is the cup?", Question("where", "cup")),
    ("find the jar within 30 seconds", Do("localise", "jar", deadline_s=30.0)),
)

REFERENCES: tuple[tuple[str, Expected], ...] = (
    # ambiguous: two cups, several containers
    ("bring me the cup", Ask("which", "Which cup: the one in the cabinet or the one on the table?")),
    ("hand me the mug", Ask("which", "Which mug:")),
    ("put the cup on the table", Ask("which", "Which cup:")),
    ("pour the jar into the cup", Ask("which", "Which cup:")),
    ("fill the cup from the jar", Ask("which", "Which cup:")),
    ("pick up the coffee cup", Ask("which", "Which coffee cup:")),
    ("return the cup", Ask("which", "Which cup:")),
    ("bring me the container", Ask("which", "Which container:")),
    ("put the jar in the container", Ask("which", "Which container:")),
    ("bring me the white one", Ask("which", "Which one:")),
    ("find the cup", Ask("which", "Which cup: the one in the cabinet or the one on the table?")),
    ("where is the mug", Ask("which", "Which mug:")),
    # resolved by where the thing is, or by an adjective
    ("bring me the one on the table", Do("bring", "cup_2")),
    ("bring me the cup on the table", Do("bring", "cup_2")),
    ("bring me the cup in the cabinet", Do("bring", "cup")),
    ("bring me the cup that is in the cabinet", Do("bring", "cup")),
    ("bring me the blue cup", Do("bring", "cup_2")),
    ("bring me the small cup", Do("bring", "cup")),
    ("fill the cup on the table from the jar", Do("pour", "jar", "cup_2")),
    ("where is the cup on the table", Question("where", "cup_2")),
    ("look for the blue cup", Do("localise", "cup_2")),
    # unknown: nothing fits
    ("bring me the small jar", Refuse("I know of no small jar: the jar is big, glass, transparent.")),
    (
        "bring me the bowl from the table",
        Refuse("I know of no bowl in or on the table: the bowl is in the cabinet"),
    ),
    ("pour the jar into the bowl on the table", Refuse("the bowl is in the cabinet")),
    ("bring me the red cup", Refuse("'red'")),
    ("bring me the teapot", Refuse("'teapot'")),
    ("pour the jar into the saucepan", Refuse("'saucepan'")),
    ("hand me the spoon", Refuse("'spoon'")),
    # "it" with nothing named before
    ("put it on the table", Ask("missing", "Which object should I put on the table?")),
    ("pour it into the bowl", Ask("missing", "Which object should I pour into the bowl?")),
    ("hand it over", Ask("missing", "What should I hand you?")),
    ("put that back", Ask("missing", "What should I put back?")),
    ("where is it?", Ask("missing", "Which object do you mean?")),
    ("locate the small jar", Refuse("I know of no small jar")),
    # possessives, wishes and phrasal verbs naming one of the two cups
    ("bring me the table's cup", Do("bring", "cup_2")),
    ("bring me the cabinet's cup", Do("bring", "cup")),
    ("pour the jar's contents into the table's cup", Do("pour", "jar", "cup_2")),
    ("I'd like the cup", Ask("which", "Which cup: the one in the cabinet or the one on the table?")),
    ("can I have the mug?", Ask("which", "Which mug:")),
    ("would you mind picking up the cup", Ask("which", "Which cup:")),
    ("take out the cup", Ask("which", "Which cup:")),
    ("put down the cup", Ask("which", "Which cup:")),
    ("I want the blue cup", Do("bring", "cup_2")),
    ("where's the blue cup?", Question("where", "cup_2")),
)

REFUSALS: tuple[tuple[str, Expected], ...] = (
    ("sing me a song", Refuse("'sing'")),
    ("dance", Refuse("'dance'")),
    ("make me a sandwich", Refuse("'make'")),
    ("open the fridge", Refuse("'open'")),
    ("wash the dishes", Refuse("'wash'")),
    ("cook dinner", Refuse("'cook'")),
    ("what is the weather like", Refuse("'what'")),
    ("why", Refuse("'why'")),
    ("pour the teapot into the bowl", Refuse("'teapot'")),
    ("bring me the spoon", Refuse("'spoon'")),
    ("put the cup on the red table", Refuse("'red'")),
    ("bring me the cups", Refuse("one object at a time")),
    ("bring me the jar and the cup", Refuse("one object at a time")),
    ("give the jar to Bob", Refuse("'bob'")),
    ("give the cup to the table", Refuse("only to you")),
    ("pour the jar into the bowl within 3 parsecs", Refuse("deadline")),
    ("pour the jar into the bowl within a while", Refuse("deadline")),
    ("put on the table the cup", Refuse("'the' after 'put on the table'")),
    ("jar bowl pour", Refuse("'bowl' after 'jar'")),
    ("the the the", Refuse("'the'")),
    ("", Refuse("empty sentence")),
    ("please", Ask("missing", "stops after 'please'")),
    ("pour", Ask("missing", "Which object should I pour?")),
    ("put the jar on", Ask("missing", "Where should I put the jar?")),
    ("pour the jar", Ask("missing", "Into what should I pour the jar?")),
    ("fill the bowl", Ask("missing", "What should I fill the bowl from?")),
    ("empty the jar", Ask("missing", "Into what should I empty the jar?")),
    ("hand me", Ask("missing", "What should I hand you?")),
    ("put the cup", Ask("missing", "Where should I put the cup?")),
    ("bring me the small jar", Refuse("no small jar")),
    ("bring me", Ask("missing", "What should I bring?")),
    ("find", Ask("missing", "What should I look for? Say e.g. 'find the jar'.")),
    ("where is", Ask("missing", "Which object do you ask about?")),
    ("look for the cups", Refuse("one object at a time")),
    ("find the jar and the cup", Refuse("one object at a time")),
    ("where is the teapot", Refuse("I have not seen a teapot")),
    ("look at the jar", Refuse("'at'")),
)

PHRASAL: tuple[tuple[str, Expected], ...] = (
    ("put away the jar", Do("return", "jar")),
    ("please put away the bowl", Do("return", "bowl")),
    ("put away the mug in the cupboard", Do("return", "cup")),
    ("put the mug away in the cupboard", Do("return", "cup")),
    ("put the cup away on the table", Do("place", "cup", "table")),
    ("take out the jar", Do("bring", "jar")),
    ("take out the jar from the cabinet", Do("bring", "jar")),
    ("take out the bowl and bring it to me", Do("bring", "bowl")),  # one command, said twice
    ("take out the bowl and bring me the cup", Refuse("'bring' after 'take out the bowl and'")),
    ("take out the salad bowl", Do("bring", "bowl")),
    ("take the cup out", Do("bring", "cup")),
    ("get out the jar", Do("bring", "jar")),
    ("get the jar out", Do("bring", "jar")),
    ("get out the bowl from the cupboard", Do("bring", "bowl")),
    ("bring out the jar", Do("bring", "jar")),
    ("bring over the jar", Do("bring", "jar")),
    ("bring over the cup to me", Do("bring", "cup")),
    ("bring back the cup", Do("bring", "cup")),
    ("fetch back the jar", Do("bring", "jar")),
    ("get down the bowl", Do("bring", "bowl")),
    ("take away the cup", Do("return", "cup")),
    ("take away the mug", Do("return", "cup")),
    ("take back the jar", Do("return", "jar")),
    ("take back the bowl to the cabinet", Do("return", "bowl")),
    ("pick up the jar", Do("fetch", "jar")),
    ("pick up the salad bowl", Do("fetch", "bowl")),
    ("could you pick up the mug?", Do("fetch", "cup")),
    ("pick the bowl up", Do("fetch", "bowl")),
    ("put down the bowl", Do("place", "bowl", "table")),
    ("put down the cup", Do("place", "cup", "table")),
    ("put the cup down", Do("place", "cup", "table")),
    ("set down the jar", Do("place", "jar", "table")),
    ("set the jar down", Do("place", "jar", "table")),
    ("lay down the bowl", Do("place", "bowl", "table")),
    ("put the bowl down please", Do("place", "bowl", "table")),
    ("put down the mug on the table", Do("place", "cup", "table")),
    ("clear away the cup", Do("return", "cup")),
    ("clear away the jar", Do("return", "jar")),
    ("clear the bowl away", Do("return", "bowl")),
    ("clear up the mug", Do("return", "cup")),
    ("tidy up the jar", Do("return", "jar")),
    ("hand over the jar", Do("hand_over", "jar")),
    ("hand over the mug to me", Do("hand_over", "cup")),
    ("pour out the jar into the bowl", Do("pour", "jar", "bowl")),
    ("pour out the beans into the bowl", Do("pour", "jar", "bowl")),
    ("empty out the glass jar into the salad bowl", Do("pour", "jar", "bowl")),
    ("fill up the bowl from the jar", Do("pour", "jar", "bowl")),
    ("fill up the bowl with the beans", Do("pour", "jar", "bowl")),
    ("fill up the dish with the contents of the jar", Do("pour", "jar", "bowl")),
)
"""Phrasal verbs, the particle before or after the object ("take out the jar", "put the cup
down": set down on the table, where the robot puts things down)."""

POSSESSIVES: tuple[tuple[str, Expected], ...] = (
    ("pour the jar's contents into the bowl", Do("pour", "jar", "bowl")),
    ("pour the jar’s contents into the bowl", Do("pour", "jar", "bowl")),
    ("pour the jars contents into the bowl", Do("pour", "jar", "bowl")),
    ("pour the jars' contents into the bowl", Do("pour", "jar", "bowl")),
    ("pour the jar contents into the bowl", Do("pour", "jar", "bowl")),
    ("pour the jar's beans into the bowl", Do("pour", "jar", "bowl")),
    ("pour the glass jar's contents into the salad bowl", Do("pour", "jar", "bowl")),
    ("pour the big jar's content into the white bowl", Do("pour", "jar", "bowl")),
    ("tip the jar's contents into the dish", Do("pour", "jar", "bowl")),
    ("empty the jar's contents into the bowl", Do("pour", "jar", "bowl")),
    ("empty the jar's beans into the bowl", Do("pour", "jar", "bowl")),
    ("fill the bowl with the jar's contents", Do("pour", "jar", "bowl")),
    ("fill the bowl with the jar's marbles", Do("pour", "jar", "bowl")),
    ("could you pour the jar's contents into the bowl?", Do("pour", "jar", "bowl")),
    ("pour all the jar's contents into the bowl", Do("pour", "jar", "bowl")),
    ("pour all the beans into the bowl", Do("pour", "jar", "bowl")),
    ("pour all of the beans into the bowl", Do("pour", "jar", "bowl")),
    ("pour everything from the jar into the bowl", Do("pour", "jar", "bowl")),
    ("pour what's inside the jar into the bowl", Do("pour", "jar", "bowl")),
    ("bring me the cabinet's cup", Do("bring", "cup")),
    ("find the jar's beans", Do("localise", "jar")),
    ("pour the bowl's contents into the jar", Do("pour", "bowl", "jar")),
    ("pour the jar's lid into the bowl", Refuse("'lid'")),
    ("pour the jar's into the bowl", Refuse("'into' after 'pour the jar's'")),
    ("bring me the table's jar", Refuse("I know of no jar in or on the table")),
)
"""Possessive containers: "the jar's contents", "the jar's beans", the apostrophe left out."""

POLITE: tuple[tuple[str, Expected], ...] = (
    ("would you mind pouring the jar into the bowl?", Do("pour", "jar", "bowl")),
    ("would you mind bringing me the cup", Do("bring", "cup")),
    ("would you mind putting the cup away", Do("return", "cup")),
    ("would you mind putting the jar on the table, please?", Do("place", "jar", "table")),
    ("would you mind picking up the mug", Do("fetch", "cup")),
    ("would you mind handing me the bowl", Do("hand_over", "bowl")),
    ("would you mind getting me the jar", Do("bring", "jar")),
    ("would you mind taking the jar out of the cabinet", Do("bring", "jar")),
    ("would you mind emptying the jar into the bowl", Do("pour", "jar", "bowl")),
    ("would you mind filling the bowl from the jar", Do("pour", "jar", "bowl")),
    ("would you mind finding the jar", Do("localise", "jar")),
    ("would you mind looking for the cup", Do("localise", "cup")),
    ("would you mind tidying the cup away", Do("return", "cup")),
    ("do you mind fetching the bowl", Do("bring", "bowl")),
    ("would you mind singing", Refuse("'singing'")),
    ("can you pour the jar into the bowl?", Do("pour", "jar", "bowl")),
    ("can you please bring me the cup", Do("bring", "cup")),
    ("will you hand me the jar?", Do("hand_over", "jar")),
    ("will you please put the cup away", Do("return", "cup")),
    ("would you please fill the bowl from the jar", Do("pour", "jar", "bowl")),
    ("could you possibly bring me the cup?", Do("bring", "cup")),
    ("could you just put the jar back", Do("return", "jar")),
    ("I need you to pour the jar into the bowl", Do("pour", "jar", "bowl")),
    ("I need you to find the cup", Do("localise", "cup")),
    ("kindly pour the jar into the bowl", Do("pour", "jar", "bowl")),
    ("would you kindly hand me the mug", Do("hand_over", "cup")),
    ("would you be so kind as to bring me the jar?", Do("bring", "jar")),
    ("be so kind and put the bowl on the table", Do("place", "bowl", "table")),
    ("if you could pour the jar into the bowl, that would be great", Do("pour", "jar", "bowl")),
    ("if you could bring me the cup, that would be lovely", Do("bring", "cup")),
    ("it would be great if you could put the jar back", Do("return", "jar")),
    ("I'd appreciate it if you could hand me the bowl", Do("hand_over", "bowl")),
    ("pour the jar into the bowl, I'd appreciate it", Do("pour", "jar", "bowl")),
    ("would it be possible to bring me the cup?", Do("bring", "cup")),
    ("is it possible for you to find the jar?", Do("localise", "jar")),
    ("are you able to pour the jar into the bowl?", Do("pour", "jar", "bowl")),
    ("do me a favour and put the cup away", Do("return", "cup")),
    ("do me a favor and fetch the jar", Do("bring", "jar")),
    ("come and get the cup", Do("bring", "cup")),
    ("hello there, could you bring me the cup?", Do("bring", "cup")),
    ("if you don't mind, put the jar on the table", Do("place", "jar", "table")),
    ("bring me the cup if you can", Do("bring", "cup")),
    ("hand me the jar if you would", Do("hand_over", "jar")),
    ("put the bowl back if possible", Do("return", "bowl")),
    ("pour the jar into the bowl when you get a chance", Do("pour", "jar", "bowl")),
    ("could you find the jar for me?", Do("localise", "jar")),
    ("get the jar for me please", Do("bring", "jar")),
    ("pour the jar into the bowl, thank you so much", Do("pour", "jar", "bowl")),
)
"""Polite framings around a command: "would you mind pouring …", "can you …", "I need you to …",
"if you could …, that would be great"."""

WISHES: tuple[tuple[str, Expected], ...] = (
    ("I'd like the cup", Do("bring", "cup")),
    ("I would like the cup, please", Do("bring", "cup")),
    ("I want the jar", Do("bring", "jar")),
    ("I need the bowl", Do("bring", "bowl")),
    ("I'd love the mug", Do("bring", "cup")),
    ("I could use the salad bowl", Do("bring", "bowl")),
    ("I would like to have the cup", Do("bring", "cup")),
    ("I'd like the cup right away", Do("bring", "cup", priority=URGENT)),
    ("I want the cup on the table", Do("bring", "cup")),
    ("I want the mug here", Do("bring", "cup")),
    ("I'd like the jar back in the cabinet", Do("return", "jar")),
    ("I'd like the jar in the cupboard", Do("return", "jar")),
    ("I want the cup over there", Ask("missing", "Where should I bring the cup?")),
    ("I'd like", Ask("missing", "What would you like?")),
    ("I'd like you to pour the jar into the bowl", Do("pour", "jar", "bowl")),
    ("I want you to bring me the cup", Do("bring", "cup")),
    ("I would like you to put the jar back", Do("return", "jar")),
    ("I'd love you to hand me the bowl", Do("hand_over", "bowl")),
    ("can I have the cup?", Do("hand_over", "cup")),
    ("could I have the jar please", Do("hand_over", "jar")),
    ("may I have the salad bowl?", Do("hand_over", "bowl")),
    ("can I get the mug", Do("hand_over", "cup")),
    ("could we have the jar, please?", Do("hand_over", "jar")),
    ("can I have", Ask("missing", "What should I hand you?")),
    ("I want the teapot", Refuse("'teapot'")),
)
"""Wishes: "I'd like the cup" (brought, as "bring me the cup"), "can I have the cup" (handed over,
as "give me the cup"), "I want you to …"."""

TAG_QUESTIONS: tuple[tuple[str, Expected], ...] = (
    ("pour the jar into the bowl, will you?", Do("pour", "jar", "bowl")),
    ("pour the jar into the bowl, would you?", Do("pour", "jar", "bowl")),
    ("pour the jar into the bowl, can you?", Do("pour", "jar", "bowl")),
    ("pour the jar into the bowl, could you?", Do("pour", "jar", "bowl")),
    ("bring me the cup, won't you?", Do("bring", "cup")),
    ("hand me the jar, would you please?", Do("hand_over", "jar")),
    ("put the cup away, will you", Do("return", "cup")),
    ("put the jar on the table, could you?", Do("place", "jar", "table")),
    ("find the jar, can you?", Do("localise", "jar")),
    ("pick up the cup, would you?", Do("fetch", "cup")),
    ("bring me the cup, okay?", Do("bring", "cup")),
    ("fill the bowl from the jar, ok?", Do("pour", "jar", "bowl")),
    ("bring me the cup now, will you?", Do("bring", "cup", priority=URGENT)),
    ("pour the jar into the bowl within a minute, will you?", Do("pour", "jar", "bowl", deadline_s=60.0)),
    ("tidy the cup away, would you, thanks", Do("return", "cup")),
)
"""Tag questions after a command: "…, will you?", "…, would you?", "…, okay?"."""

DEADLINES: tuple[tuple[str, Expected], ...] = (
    ("pour the jar into the bowl within two minutes", Do("pour", "jar", "bowl", deadline_s=120.0)),
    ("pour the jar into the bowl in five minutes", Do("pour", "jar", "bowl", deadline_s=300.0)),
    ("pour the jar into the bowl within a minute", Do("pour", "jar", "bowl", deadline_s=60.0)),
    ("pour the jar into the bowl in half a minute", Do("pour", "jar", "bowl", deadline_s=30.0)),
    ("bring me the cup within half an hour", Do("bring", "cup", deadline_s=1800.0)),
    ("bring me the cup in an hour", Do("bring", "cup", deadline_s=3600.0)),
    ("bring me the cup in one hour", Do("bring", "cup", deadline_s=3600.0)),
    ("put the cup away within twenty seconds", Do("return", "cup", deadline_s=20.0)),
    ("put the cup away within twenty five seconds", Do("return", "cup", deadline_s=25.0)),
    ("put the cup away within twenty-five seconds", Do("return", "cup", deadline_s=25.0)),
    ("put the cup away in forty-five seconds", Do("return", "cup", deadline_s=45.0)),
    ("hand me the jar within eleven seconds", Do("hand_over", "jar", deadline_s=11.0)),
    ("hand me the jar within twelve minutes", Do("hand_over", "jar", deadline_s=720.0)),
    ("hand me the jar within fifty nine seconds", Do("hand_over", "jar", deadline_s=59.0)),
    ("hand me the jar within sixty seconds", Do("hand_over", "jar", deadline_s=60.0)),
    ("find the cup in three minutes", Do("localise", "cup", deadline_s=180.0)),
    ("find the cup in the next three minutes", Do("localise", "cup", deadline_s=180.0)),
    ("find the cup in under a minute", Do("localise", "cup", deadline_s=60.0)),
    ("find the cup in less than 90 seconds", Do("localise", "cup", deadline_s=90.0)),
    ("pour the jar into the bowl within a quarter of an hour", Do("pour", "jar", "bowl", deadline_s=900.0)),
    ("pour the jar into the bowl within a couple of minutes", Do("pour", "jar", "bowl", deadline_s=120.0)),
    ("pour the jar into the bowl within one and a half minutes", Do("pour", "jar", "bowl", deadline_s=90.0)),
    ("in two minutes, pour the jar into the bowl", Do("pour", "jar", "bowl", deadline_s=120.0)),
    ("within seventeen seconds put the jar back", Do("return", "jar", deadline_s=17.0)),
    ("pick up the cup within 10 secs", Do("fetch", "cup", deadline_s=10.0)),
    ("put the jar in the cabinet in 2 mins", Do("return", "jar", deadline_s=120.0)),
    ("put the jar in the cabinet within 1 hr", Do("return", "jar", deadline_s=3600.0)),
    (
        "quickly put the cup on the table within thirty seconds",
        Do("place", "cup", "table", priority=URGENT, deadline_s=30.0),
    ),
    ("put the jar in a minute", Ask("missing", "Where should I put the jar?")),
    ("pour the jar into the bowl in 5 parsecs", Refuse("deadline")),
    ("pour the jar into the bowl within a few minutes", Refuse("deadline")),
    ("pour the jar into the bowl within seventy minutes", Refuse("deadline")),
)
"""Deadlines in number words and with "in": "within two minutes", "in half a minute", "in under
a minute"; one not understood is refused."""

LOCALISE: tuple[tuple[str, Expected], ...] = (
    ("where's the cup?", Question("where", "cup")),
    ("where’s the jar", Question("where", "jar")),
    ("where are the beans?", Question("where", "jar")),
    ("could you tell me where the jar is?", Do("localise", "jar")),
    ("tell me where the bowl is, please", Do("localise", "bowl")),
    ("do you know where the mug is?", Do("localise", "cup")),
    ("have you seen the jar?", Do("localise", "jar")),
    ("can you find the salad bowl?", Do("localise", "bowl")),
    ("search for the glass jar right away", Do("localise", "jar", priority=URGENT)),
    ("check where the cup is", Do("localise", "cup")),
    ("locate the bowl within a minute", Do("localise", "bowl", deadline_s=60.0)),
    ("look for the jar's beans", Do("localise", "jar")),
    ("where's", Ask("missing", "Which object do you ask about?")),
    ("have you seen", Ask("missing", "What should I look for?")),
    ("do you know where the teapot is", Refuse("'teapot'")),
)
"""More words for localise (tasks.toml): "where's …", "do you know where … is"."""

BAD_INPUT: tuple[tuple[str, Expected], ...] = (
    # a deadline that has passed or leaves no time
    ("pour the jar into the bowl within -5 seconds", Refuse("'within -5 seconds' is negative")),
    ("pour the jar into the bowl within -1 minutes", Refuse("is negative")),
    ("bring me the cup in -10 seconds", Refuse("'in -10 seconds' is negative")),
    ("bring me the cup within −2 minutes", Refuse("is negative")),
    ("bring me the cup within --3 seconds", Refuse("is negative")),
    ("pour the jar into the bowl within 0 seconds", Refuse("'within 0 seconds' leaves no time")),
    ("pour the jar into the bowl within 0.0 minutes", Refuse("leaves no time")),
    ("pour the jar into the bowl within zero seconds", Refuse("leaves no time")),
    ("put the cup away in zero minutes", Refuse("leaves no time")),
    # control characters: refused, not read as spaces
    ("pour the jar\x00 into the bowl", Refuse("control character (U+0000")),
    ("\x1b[31mpour the jar into the bowl", Refuse("control character (U+001B")),
    ("pour the jar into the bowl\x07", Refuse("control character (U+0007")),
    ("bring me\x08\x08 the cup", Refuse("control character (U+0008")),
    ("bring me the cup\x7f", Refuse("control character (U+007F")),
    ("bring me the\x85cup", Refuse("control character (U+0085")),
    ("bring me the\x9bcup", Refuse("control character (U+009B")),
    ("bring me\x0bthe cup", Refuse("control character (U+000B")),
    ("bring me\x0cthe cup", Refuse("control character (U+000C")),
    ("bring me\x1cthe cup", Refuse("control character (U+001C")),
    ("stop\x00", Refuse("control character (U+0000")),
    ("bring me\tthe cup", Do("bring", "cup")),
    ("bring me the cup\r\n", Do("bring", "cup")),
    # a place a_hi cannot see: a question back, not a guess
    (
        "put the cup over there",
        Ask("missing", "Where should I put the cup? I cannot tell where 'over there' is"),
    ),
    ("put the cup there", Ask("missing", "Where should I put the cup? I cannot tell where 'there' is")),
    ("put the jar somewhere", Ask("missing", "Where should I put the jar?")),
    ("put it somewhere", Ask("missing", "Which object should I put?")),
    ("set the bowl down somewhere else", Ask("missing", "Where should I put the bowl?")),
    ("place the mug anywhere", Ask("missing", "Where should I put the cup?")),
    ("put the jar in there", Ask("missing", "Where should I put the jar?")),
    ("move the bowl over that way", Ask("missing", "Where should I put the bowl?")),
    ("bring the cup over there", Ask("missing", "Where should I bring the cup?")),
    ("take the jar somewhere", Ask("missing", "Where should I bring the jar?")),
    ("put the cup back over there", Ask("missing", "Where should I put the cup?")),
    ("pour the jar over there", Ask("missing", "Into what should I pour the jar?")),
    ("bring me the cup over there", Do("bring", "cup")),
)
"""Input refused with one line naming what is wrong (a negative or zero deadline, a control
character), and vague places asked back ("Where should I put the cup?") rather than guessed."""


VOICES: tuple[tuple[str, Expected], ...] = (
    # what is in a container, moved into another: a pour, never the container put inside it
    ("I'd like the beans in the bowl, please", Do("pour", "jar", "bowl")),
    ("can you put the beans into the bowl", Do("pour", "jar", "bowl")),
    ("put the contents of the jar into the bowl", Do("pour", "jar", "bowl")),
    # self-corrections: the later words replace the earlier
    ("bring me the jar, sorry, I mean the bowl", Do("bring", "bowl")),
    ("put the cup, er, the bowl on the table", Do("place", "bowl", "table")),
    ("bring me the cup, sorry, pour the jar into the bowl", Do("pour", "jar", "bowl")),
    ("bring me the jar, um, actually the cup", Do("bring", "cup")),
    # follow-ups, openers, endearments, a clause that carries nothing
    ("and then bring me the cup", Do("bring", "cup")),
    ("then put the cup away", Do("return", "cup")),
    ("bring me the cup, would you, love?", Do("bring", "cup")),
    ("Hiya robot! bring me the cup", Do("bring", "cup")),
    ("I'm thirsty, bring me my cup", Do("bring", "cup")),
    ("oh dear, bring me the jar", Do("bring", "jar")),
    # word order of another language
    ("Put please the bowl on table", Do("place", "bowl", "table")),
    ("give to me the jar", Do("hand_over", "jar")),
    ("bring me cup", Do("bring", "cup")),
    # a comparison with the words a_km describes things with
    ("bring me the smaller cup", Do("bring", "cup")),
    ("bring me the biggest jar", Do("bring", "jar")),
    ("fetch the larger bowl", Do("bring", "bowl")),
    # progress asked in other words
    ("how much longer will you be?", STATUS),
    ("any progress on that?", STATUS),
    ("any progress on it yet?", STATUS),
    ("what did you see just now?", Question("seen")),
)
"""Sentences in other voices (a hurried parent, a child, someone chatty, a non-native speaker),
from a review by people who had read only the documentation: what people add around a command
or correct in it (tolerance.py), and a content named for its container."""

VOICES_REFUSED: tuple[tuple[str, Expected], ...] = (
    # never a command the person did not mean: a negation, a second request, another script
    ("don't, bring me the cup", Refuse("'dont'")),
    ("no, bring me the cup", Refuse("'no'")),
    ("pour the jar into the bowl. Then burn the house down", Refuse("'then'")),
    ("pour the jar into the bowl, and then smash the window", Refuse("'smash'")),
    ("bring me the cup, and the jar", Refuse("one object at a time")),
    ("カップを持ってきて", Refuse("That line is in Japanese script")),
    ("принеси чашку", Refuse("That line is in Cyrillic script")),
    ("🍵🍵", Refuse("I heard no words in that line, only symbols")),
    # a refusal names only words a_hi does not know
    ("pour the jar into the bowl withim 2 minutes", Refuse("I do not know the word 'withim' here;")),
    ("bring me the smaller bowl", Refuse("I know of no small bowl: the bowl is ceramic, large, white")),
    # a correction after two objects: which one it corrects is not known
    ("put the cup on the table, sorry, the bowl", Refuse("'sorry'")),
)
"""Lines of the same review that must still be refused, each with what the refusal names."""
