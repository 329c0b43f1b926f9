"""The corpus: sentences a person in the kitchen says, each with what a_hi must make of it — an
L_HC command (or stop, or status request), a question back, or a refusal that names the word or
the missing part. test_corpus.py runs every sentence. It covers every task a_pl accepts, those
whose frames are grammar.lark's and those whose frames are tasks.toml's (fetch, the tidy frames of
return, localise).

- :data:`PARAPHRASES`: different wordings of the tasks, against the kitchen as O_RoCo states it
  (one jar, bowl, cup, table, cabinet);
- :data:`REFERENCES`: ambiguous, unknown and located references, against the kitchen with a
  second cup standing on the table (:data:`SECOND_CUP`, a fact stated as a_km would hold it);
- :data:`REFUSALS`: sentences a_hi must not turn into a command.
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


STOP = "stop"
STATUS = "status"
Expected = Do | Ask | Refuse | str

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
    ("grab the bowl", Do("bring", "bowl")),
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
    ("where is the bowl?", Do("localise", "bowl")),
    ("locate the jar", Do("localise", "jar")),
    ("could you find the glass jar, please?", Do("localise", "jar")),
    ("please look for the coffee mug", Do("localise", "cup")),
    ("robot, where is the salad bowl?", Do("localise", "bowl")),
    ("search for the table", Do("localise", "table")),
    ("look where the cup is", Do("localise", "cup")),
    ("show me where the bowl is", Do("localise", "bowl")),
    ("find the beans", Do("localise", "jar")),
    ("where is the jar in the cabinet", Do("localise", "jar")),
    ("stop", STOP),
    ("Stop everything!", STOP),
    ("please stop now", STOP),
    ("cancel", STOP),
    ("stop it", STOP),
    ("abort all tasks", STOP),
    ("halt", STOP),
    ("stop whatever you are doing", STOP),
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
    ("quickly, where is the cup?", Do("localise", "cup", priority=URGENT)),
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
    ("where is the cup on the table", Do("localise", "cup_2")),
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
    ("where is it?", Ask("missing", "What should I look for? Say e.g. 'find the jar'.")),
    ("locate the small jar", Refuse("I know of no small jar")),
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
    ("stop the pouring", Refuse("say 'stop'")),
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
    ("put the cup down", Ask("missing", "Where should I put the cup?")),
    ("bring me the small jar", Refuse("no small jar")),
    ("bring me", Ask("missing", "What should I bring?")),
    ("find", Ask("missing", "What should I look for? Say e.g. 'find the jar'.")),
    ("where is", Ask("missing", "What should I look for?")),
    ("look for the cups", Refuse("one object at a time")),
    ("find the jar and the cup", Refuse("one object at a time")),
    ("where is the teapot", Refuse("'teapot'")),
    ("look at the jar", Refuse("'at'")),
)
