"""Hypothesis strategies and sample terms shared by the fipa_codec tests."""

from __future__ import annotations

from typing import Literal

import msgspec
from hypothesis import strategies as st

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    Arm,
    CommandResult,
    Grasp,
    LookAt,
    MoveJoints,
    MoveTool,
    Observe,
    PowerOn,
    PowerOns,
    Release,
    Tilt,
    Wait,
    Watch,
)
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Notice,
    Progress,
    ProgressSubscription,
    Sentence,
    SentenceReport,
    Severity,
    Status,
    StatusQuery,
    TaskAtom,
    TaskState,
    TaskStatus,
)
from shared.fipa_codec.languages.l_hfsm import (
    Assert,
    CheckContent,
    Execute,
    ExpectedPosition,
    GroundTaskNetwork,
    HierarchicalPlan,
    Perceive,
    PlanFailure,
    PlanNode,
)
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspAffordance,
    GraspQuery,
    GraspStep,
    HypotheticalQuery,
    ObjectInfo,
    ObjectQuery,
    ObjectUpdate,
    PlacementInfo,
    PlacementQuery,
    PourAffordance,
    PourQuery,
    PourStep,
    PutStep,
    SceneChange,
    SceneQuery,
    SceneSubscription,
    SparqlQuery,
    Subscription,
    WorldUpdate,
)
from shared.fipa_codec.names import is_word

POSE = Pose((0.6, -0.1, 1.02), (0.707, 0.0, 0.707, 0.0), "world")
MOVE = MoveTool(arm=Arm.RIGHT, target=POSE, duration=2.5, stiffness=(800, 800, 800, 50, 50, 50))
PLAN_ROOT = PlanNode(
    name="pour_jar_bowl",
    task="pour",
    children=(
        PlanNode(name="look", action=Perceive(("jar", "bowl"))),
        PlanNode(
            name="fetch_jar",
            children=(
                PlanNode(name="approach", action=Execute(MOVE)),
                PlanNode(name="grasp", action=Execute(Grasp(arm=Arm.RIGHT, spread=0.1))),
                PlanNode(
                    name="held",
                    action=Assert(subject="jar", relation="heldBy", object="right_hand"),
                ),
            ),
        ),
        PlanNode(name="check", action=CheckContent(container="bowl", min_fraction=0.8)),
    ),
)

SAMPLE_TERMS: list[msgspec.Struct] = [
    # L_HC
    HumanCommand(text="Pour the jar into the bowl", goal=TaskAtom("pour", ("jar", "bowl"))),
    HumanCommand(text="żółw", goal=TaskAtom("fetch"), priority=3, deadline_s=60.0),
    CommandOutcome(command_id="cmd-1", succeeded=True, detail="done"),
    ProgressSubscription(),
    Progress(command_id="cmd-1", state=TaskState.RUNNING, step="pour(jar,bowl)/fetch_jar/grasp"),
    StatusQuery(),
    Sentence(text="bring me the cup"),
    SentenceReport(kind="succeeded", text="bring the cup: succeeded; done"),
    Notice(text="the jar tipped over", severity=Severity.WARNING, about=("jar",)),
    Status(
        tasks=(
            TaskStatus(command_id="cmd-1", text="pour", state=TaskState.PREEMPTED, priority=1),
            TaskStatus(command_id="cmd-2", text="fetch", state=TaskState.RUNNING, deadline_in_s=-3.5),
        )
    ),
    # L_HFSM
    GroundTaskNetwork(task_id="t1", tasks=(TaskAtom("pour", ("jar", "bowl")),), plan_index=2),
    HierarchicalPlan(plan_id="p1", task_id="t1", root=PLAN_ROOT, complete=False, cost=12.5),
    HierarchicalPlan(
        plan_id="p2",
        task_id="t1",
        root=PlanNode(
            name="r", children=(PlanNode(name="a", action=Perceive(), on_cancel="s0"),), atomic=True
        ),
        safe_stops={"s0": PLAN_ROOT},
    ),
    Perceive(("jar",), expect=(ExpectedPosition(object="jar", position=(0.8, 0.2, 0.9), tolerance=0.02),)),
    PlanFailure(task_id="t1", reason="no jar"),
    Execute(Wait(duration=0.5)),
    Perceive(),
    Assert(subject="jar", relation="on", object=""),
    CheckContent(container="bowl", min_fraction=0.5),
    # L_SW
    *[SWStatus(state=s, plan_id="p1", step="fetch_jar/grasp", reason="r") for s in SWState],
    SWStatus(state=SWState.IDLE),
    # L_WM
    SparqlQuery("SELECT ?x WHERE { ?x a roco:Container }"),
    ObjectQuery("jar"),
    SceneQuery(),
    GraspQuery(object="jar", arm="right"),
    PlacementQuery(object="jar", surface="table"),
    PourQuery(source="jar", target="bowl"),
    HypotheticalQuery(
        changes=(ObjectUpdate(name="jar", location="table", relation="on", held_by=""),),
        query=SparqlQuery("ASK { roco:jar roco:on roco:table }"),
    ),
    HypotheticalQuery(
        steps=(
            GraspStep(
                index=9, object="jar", arm="left", changes=(ObjectUpdate(name="jar", held_by="left_gripper"),)
            ),
            PutStep(index=30, object="jar", furniture="table", relation="on", position=(0.1, -0.5, 0.75)),
            PourStep(index=41, source="jar", target="bowl", changes=(ObjectUpdate(name="jar", particles=0),)),
        ),
        query=SparqlQuery("ASK { }"),
    ),
    Subscription(),
    Subscription("watch", period_s=0.25),
    Answer(
        objects=(
            ObjectInfo(
                name="jar",
                type="Jar",
                pose=POSE,
                pose_stamp=1.5,
                size=(0.08, 0.08, 0.15),
                location="table",
                relation="on",
                localised=True,
                particles=120,
            ),
        ),
        grasps=(GraspAffordance(name="side", grip_in_object=POSE, approach=(1.0, 0.0, 0.0), distance=0.1),),
        placement=PlacementInfo(surface="table", positions=((0.5, 0.0, 0.75),)),
        pour=PourAffordance(
            facing=-1.2,
            source_in_target=(0.0, -0.07, 0.08),
            approach_height=0.08,
            pivot_in_target=(0.0, -0.06, 0.14),
            axis=(1, 0, 0),
            angle=-2.3,
            duration=4.0,
        ),
        variables=("x",),
        rows=(("a", None),),
        boolean=True,
    ),
    Answer(),
    WorldUpdate(
        stamp=3.0,
        objects=(ObjectUpdate(name="jar", pose=POSE, held_by="", particles=0),),
        total_particles=200,
    ),
    SceneSubscription(objects=("jar", "bowl"), moved=0.02, tilted=None, content=False, queue=8),
    SceneSubscription(objects=("bowl",), within_s=0.5),
    SceneChange(
        object="jar",
        changed=("moved", "tilted"),
        stamp=4.5,
        seen_at=1700000000.25,
        pose=POSE,
        distance=0.12,
        tilt=1.57,
        held_by="",
        location="table",
        relation="on",
        dropped=3,
    ),
    # L_EX
    MOVE,
    MoveTool(arm=Arm.LEFT, target=POSE, duration=1.5, guard=5.0),
    MoveJoints(positions={"torso_0_joint": 0.3, "left_arm_3_joint": -1.2}, duration=2.0),
    Grasp(arm=Arm.LEFT),
    Grasp(arm=Arm.RIGHT, spread=0.1, at=POSE, tolerance=0.015),
    Release(arm=Arm.LEFT, opening=0.2),
    LookAt(point=(1.0, 0.0, 1.0)),
    Tilt(arm=Arm.RIGHT, pivot=(0.5, 0, 1), axis=(1, 0, 0), angle=1.9, duration=4.0),
    Observe(objects=("jar",)),
    Wait(duration=1.0),
    CommandResult(command="grasp", ok=False, reason="no contact", sim_time=4.2, tool_error=0.01),
    CommandResult(command="wait", ok=True, sim_time=1.5, world="roco_4242_0a1b2c3d"),
    PowerOns(),
    PowerOn(world="roco_4242_0a1b2c3d"),
    Watch(objects=("bowl", "jar"), period_s=0.25),
    CommandResult(command="move_tool", ok=True, sim_time=9.1, self_contacts=("left_arm_5 + left_arm_3",)),
    CommandResult(
        command="move_tool",
        ok=True,
        reason="contact (7.9 N, 20.0 mm from the target)",
        sim_time=8.4,
        tool_error=0.02,
        contact=7.9,
    ),
    # L_SD
    Observation(
        stamp=2.0,
        objects=(ObjectObservation(name="bowl", pose=POSE, particles_inside=17),),
        total_particles=200,
    ),
]

# ---------------------------------------------------------------------------------------------
# Strategies

_SURROGATES: tuple[Literal["Cs"], ...] = ("Cs",)
roco_names = st.from_regex(r"[A-Za-z][A-Za-z0-9_.\-@]{0,15}", fullmatch=True)
# FIPA SC00070 words: any first character but white space, ( ) # - @ " and digits, then any but
# white space and parentheses; not lexically a number or date-time (shared.fipa_codec.names)
_word_first = st.characters(
    exclude_categories=_SURROGATES, exclude_characters='()#-@"0123456789', min_codepoint=0x21
)
_word_rest = st.characters(exclude_categories=_SURROGATES, exclude_characters="()", min_codepoint=0x21)
fipa_words = st.tuples(_word_first, st.text(_word_rest, max_size=15)).map("".join).filter(is_word)
# JADE's default agent names: local@host:port/JADE
_hosts = st.from_regex(r"[a-z][a-z0-9.\-]{0,10}", fullmatch=True)
jade_names = st.builds("{}@{}:{}/JADE".format, roco_names, _hosts, st.integers(1, 65535))
agent_names = roco_names | jade_names | fipa_words
# addresses: URLs of the kinds roco and JADE use, or any SC00070 word (SC00070 §2.2 URLSequence)
_urls = ["tcp/127.0.0.1:7447", "http://robolab:7778/acc", "http://host:7778/acc?x=1"]
addresses_ = st.sampled_from(_urls) | fipa_words
any_text = st.text(max_size=30)
# keys: X- plus a name without white space or parentheses (writable in the string form)
user_keys = st.tuples(
    st.sampled_from(["X-", "x-"]),
    st.text(
        st.characters(exclude_characters="()", exclude_categories=_SURROGATES, min_codepoint=0x21),
        min_size=1,
        max_size=12,
    ),
).map("".join)
# user-defined parameters of an agent identifier: (name, value) pairs, each name once
aid_user_params = st.lists(st.tuples(user_keys, any_text), max_size=2, unique_by=lambda kv: kv[0]).map(tuple)


def agent_identifiers(depth: int = 3) -> st.SearchStrategy[AgentIdentifier]:
    """Agent identifiers (SC00023 §4) with addresses, user parameters and resolvers nested
    at most ``depth`` identifiers deep (counting the outer one); mostly plain ones."""
    addresses = st.lists(addresses_, max_size=3).map(tuple)
    plain = st.builds(AgentIdentifier, agent_names, addresses)
    if depth <= 1:
        resolvers: st.SearchStrategy[tuple[AgentIdentifier, ...]] = st.just(())
    else:
        resolvers = st.just(()) | st.lists(agent_identifiers(depth - 1), min_size=1, max_size=2).map(tuple)
    full = st.builds(AgentIdentifier, agent_names, addresses, resolvers, aid_user_params)
    return plain | full


agents = agent_identifiers()
# reply-by at millisecond resolution, years 0001-9999 (what the string form carries)
reply_times = st.integers(-62_135_596_800_000, 253_402_300_799_999).map(lambda ms: ms / 1000)
language_content = st.sampled_from(SAMPLE_TERMS).map(encode_content)


@st.composite
def contents(draw: st.DrawFn) -> tuple[bytes, str | None]:
    """(content bytes, language): binary, text, or a term of a content language."""
    kind = draw(st.sampled_from(["binary", "text", "term", "empty"]))
    if kind == "binary":
        return draw(st.binary(max_size=64)), draw(st.none() | any_text)
    if kind == "text":
        return draw(st.text(max_size=40)).encode(), draw(st.none() | any_text)
    if kind == "term":
        language, data = draw(language_content)
        return data, language
    return b"", None


@st.composite
def communicates(draw: st.DrawFn) -> Communicate:
    """Arbitrary communicates: every performative, every parameter optional."""
    content, language = draw(contents())
    opt_text = st.none() | any_text
    return Communicate(
        performative=draw(st.sampled_from(Performative)),
        sender=draw(st.none() | agents),
        receiver=tuple(draw(st.lists(agents, max_size=4))),
        reply_to=tuple(draw(st.lists(agents, max_size=2))),
        content=content,
        language=language,
        encoding=draw(st.none() | st.just("msgpack") | any_text),
        ontology=draw(opt_text),
        protocol=draw(st.none() | st.sampled_from(["fipa-request", "coordinate"]) | fipa_words),
        conversation_id=draw(opt_text),
        reply_with=draw(opt_text),
        in_reply_to=draw(opt_text),
        reply_by=draw(st.none() | reply_times),
        user_params=draw(st.dictionaries(user_keys, any_text, max_size=3)),
    )


def full_communicate(performative: Performative = Performative.INFORM) -> Communicate:
    """A communicate with every one of the 13 SC00061 parameters and a user parameter set; its
    reply-to agent identifier has a resolver and user-defined parameters (SC00023 §4)."""
    language, content = encode_content(ObjectQuery("jar"))
    return Communicate(
        performative=performative,
        sender=AgentIdentifier("a_pl", ("tcp/127.0.0.1:7447",)),
        receiver=(AgentIdentifier("a_km"), AgentIdentifier("a_ta", ("tcp/10.0.0.2:7447",))),
        reply_to=(
            AgentIdentifier(
                "a_co",
                resolvers=(AgentIdentifier("df", ("tcp/10.0.0.9:7447",)),),
                user=(("X-role", "coordinator"), ("X-note", "a (b) c")),
            ),
        ),
        content=content,
        language=language,
        encoding="msgpack",
        ontology="O_RoCo",
        protocol="fipa-query",
        conversation_id="c-ab12cd34ef56",
        reply_with="rw-1",
        in_reply_to="rw-0",
        reply_by=1795275000.123,
        user_params={"X-priority": "2", "X-note": 'with "quotes" and \\ (parens)'},
    )
