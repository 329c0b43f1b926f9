"""a_ta — the task executor (paper §5.5, Table 6, Figure 11d).

FSM states: idle (await a plan from a_co by the coordinate protocol), running (the plan is a
hierarchical FSM; its leaf states send L_EX requests to ag_ex on C5 and inform a_km of
changes on C6; every state change is informed to a_co in L_SW), finished (await a_co's
confirmation of the final state). a_km's fipa-subscribe to environment updates is answered
in every state; the first observation of the scene is taken at start-up (paper Table 7,
0–37 s: initial knowledge).

Safe interruption (paper §3.2): a ``cancel`` from a_co makes a_ta at once cancel the request
ag_ex is running (FIPA cancel on C5, even inside an atomic state), so that ag_ex halts the
commanded motion (velma/executor/loop.py ``ControlLoop.cancel``: braked to rest; mid-pour the
jar turned upright), and report Terminating. Once ag_ex answers that the command was halted,
a_ta makes the robot safe from where it stopped (``_after_halt``) and only then reports
Preempted:

- outside an atomic state, or in a pour's tilt (the halt left the jar upright), it runs the
  safe-stop HFSM the halted leaf names (the planner computed it for what the hands hold
  there: put it down in a safe place); its moves are absolute targets, reached from wherever
  the halt left the arm;
- after a torso turn halted half-way with something in hand it first turns the torso back to
  where the plan's last turn put it (the safe stops are planned for the torso there), or, when
  this plan turned it before none, on to the halted turn's target (then the next leaf's safe
  stop);
- in a take or a set-down it runs the rest of that atomic state from the halted leaf (its
  targets are absolute: a half-closed grasp closes, a half-lifted object is lifted out, a
  half-lowered one set down), then the safe stop the leaf after it names. (A take is finished,
  not undone: undone, the open hand stays at the pre-grasp pose, between the head camera and
  the object, and the next plan cannot see it.)

A command that ended before ag_ex could halt it (ag_ex answers the cancel ``failure`` with the
command's result; or its result crossed the cancel, and the ``failure`` that follows it tells
nothing), or a cancel that comes between two leaves, counts the leaf as done:
outside an atomic state the safe stop the next leaf names runs; inside one the next leaf is
sent and cancelled at once, and ag_ex halts the robot as it stands (a tilted jar turned
upright) before the above. It never opens a hand that holds something outside such a plan.

When the world differs from the plan — an object is not where a Perceive step expects it,
a grasp closes on nothing, a held object slips out — a_ta observes the scene, informs a_km of
what it saw, and reports Replan with the difference in words.

The watch (services/agents/task_executor/watching.py): a_km's second subscription on C6
(``Subscription`` topic ``watch``) has a_ta subscribe to ag_ex's watch on C5 (L_EX ``Watch``);
each frame ag_ex informs goes to a_km as an observation, and changes none of a_ta's decisions.

Restarts (docs/recovery.md): each L_SW inform is retransmitted until a_co confirms it
(a_co may be restarting); a request to ag_ex is sent again when ag_ex's liveliness token
reappears (a restarted ag_ex attached to the running world). The coordinate role keeps the
plan's conversation across a restart with a_ta's note of it (``keep=PlanNote``: the leaf step,
noted at every :meth:`TaskExecutor.persist`, and the final state once reached) for as long as
a_ta runs the plan (even once a not-understood from a restarted a_co ended it), and takes it
back in ``running`` (``resume_in``) whatever state it was in. A restarted a_ta
(:meth:`TaskExecutor.on_restored`) does not guess where the robot got to: it reports Replan
(or the final state it had reached) in the plan's conversation, once it has observed the scene
and informed a_km, so that a_co plans again from the world as it is (a_pl then first finishes a
take the restart interrupted after its grasp: ``services.agents.planner.domain.finish_takes``).
Meanwhile ag_ex holds position with the hands as they are. A take interrupted *before* its
grasp closed (a_ta restarted in it, or ag_ex held position in it) is undone by a_ta itself
before it reports: the hand is opened and moved back along the plan's way in
(``services.agents.task_executor.retreat``), then the scene is observed.
"""

from __future__ import annotations

from collections import deque

import msgspec

from services.runtime.agent import FSM, RESEND_ON_RETURN, Agent, Arc, Behaviour, Transport
from services.runtime.roles import (
    INITIATOR,
    PARTICIPANT,
    Conversation,
    StandingSubscription,
    handles,
    initiator,
    participant,
)
from services.spec.model import SystemSpec
from services.spec.names import (
    C1,
    C5,
    C6,
    COORDINATE,
    FIPA_QUERY,
    FIPA_REQUEST,
    FIPA_SUBSCRIBE,
    L_EX,
    L_HFSM,
    L_SD,
    L_SW,
    L_WM,
)
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_ex import (
    HALTED,
    TORSO_JOINT,
    CommandResult,
    LookAt,
    MoveJoints,
    Observe,
    PowerOn,
    PowerOns,
    Tilt,
    Watch,
    command_name,
)
from shared.fipa_codec.languages.l_hfsm import (
    Assert,
    CheckContent,
    Execute,
    HierarchicalPlan,
    Perceive,
    PlanNode,
)
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.languages.l_wm import ObjectUpdate, Subscription, WorldUpdate

from .expected import expected_s
from .retreat import RetreatStep, finish_set_down, undo_take
from .verdict import Answer, Do, Step, Verdict, judge
from .watching import TOPIC as WATCH_TOPIC
from .watching import WATCH_REPLY_BY_S, WatchRelay

OBSERVE_REPLY_BY_S = 30.0
LOOK_REPLY_BY_S = 10.0
"""How long a second view's head turn may take before a_ta gives up on it (s)."""
INITIAL_OBSERVE_RETRY_S = 3.0
INITIAL_OBSERVE_KEPT = 20
"""How many unanswered initial observes a_ta still takes a late answer of."""
COMMAND_MARGIN_S = 60.0
HALT_REPLY_BY_S = 30.0
"""How long ag_ex may take to answer a cancel of the command it runs (s): the halt brings the
robot to rest first (mid-pour up to the tilt's end and the turn upright, ≈ 4 s)."""
SW_RETRY_S = 5.0
"""Retransmission period of an unconfirmed L_SW inform, sent until a_co confirms it (a_co may be
restarting or away): the coordinate protocol lets a_ta send its next state only after that."""
_ENDS = {Do.REPLAN: SWState.REPLAN, Do.ERROR: SWState.ERROR}
"""The final state of each verdict that ends the plan (services/agents/task_executor/verdict.py)."""
WORLD_TIME_SLACK_S = 1e-6
POWER_ONS_REPLY_BY_S = 5.0
"""How long (s) a_ta waits for ag_ex to agree to its subscription to the robot's power-ons
before it subscribes again."""
"""How far (s) an answer's simulated time may lie before the latest one seen and still be the
same world's (the times are the world's own; equal times are the same instant)."""


def observed_update(obs: Observation, seen_at: float | None = None) -> WorldUpdate:
    """The C6 inform content a_ta sends a_km for ag_ex's L_SD observation ``obs``: each object
    seen (pose, content count, position sigma) and the hands' grip frames under the grippers'
    names (a_pl finishes a take from where the hand is), at ``obs.stamp`` (simulated s);
    ``seen_at``: a_ta's wall clock when it received ``obs`` (POSIX s), None when unknown."""
    return WorldUpdate(
        stamp=obs.stamp,
        objects=tuple(
            ObjectUpdate(
                name=o.name, pose=o.pose, particles=o.particles_inside, position_sigma=o.position_sigma
            )
            for o in (*obs.objects, *obs.grips)
        ),
        total_particles=obs.total_particles,
        seen_at=seen_at,
    )


class PlanNote(msgspec.Struct, kw_only=True):
    """What a_ta notes of the plan it runs: the data of its C1 conversation, which the role
    keeps across a restart with the plan request (``keep=PlanNote``; docs/recovery.md):
    ``step``, the path of the leaf state it is in (between two leaves: the next one), and
    ``outcome`` and ``reason``, the final state once reached."""

    step: str | None = None
    outcome: SWState | None = None
    reason: str | None = None


class TaskExecutor(Agent):
    name = "a_ta"
    ROLES = (
        # a kept plan is taken back in running whatever state it was in: a_ta reports on it
        participant(C1, COORDINATE, L_HFSM, L_SW, keep=PlanNote, resume_in="running", confirmed_informs=True),
        initiator(C5, FIPA_REQUEST, L_EX, L_SD),
        # the robot's power-ons (a world started anew), told by ag_ex as they happen; and its
        # watch (camera frames, L_SD), while a_km asks for one
        initiator(C5, FIPA_SUBSCRIBE, L_EX, L_SD, reply_by_s=POWER_ONS_REPLY_BY_S, resubscribes=True),
        participant(C6, FIPA_SUBSCRIBE, L_WM),
        # paper Table 6: a_ta may query a_km when it needs knowledge; roco's plans carry what
        # a_ta needs (expected poses, safe stops), so it asks nothing
        initiator(C6, FIPA_QUERY, L_WM, unused=True),
    )

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
        """a_ta's memory (paper §3.2: the agent's internal memory), then the runtime's
        (:class:`~services.runtime.agent.Agent`), which builds the FSM and may give a kept
        plan back (:meth:`on_restored`)."""
        self.restored = False
        self.subscription: Conversation | None = None
        self.initial_observe: Conversation | None = None
        self.initial_asked: list[Conversation] = []
        """The initial observes asked since the last one answered (any answer will do)."""
        self.initial_done = False
        self.world_time: float | None = None  # the latest simulated time ag_ex answered at (s)
        self.world: str | None = None
        """The robot's power-on ag_ex's answers last named (L_EX ``CommandResult.world``)."""
        self.worlds_before: set[str] = set()
        """The power-ons before it: a late answer from one of them is no new power-on."""
        self.renew_km = False
        """The robot was power-cycled: the next observation a_km learns renews its world."""
        self.distrust_plan = False
        """The robot was power-cycled: the next leaf answered (of the plan running then, or of
        the next one, which may have been planned before a_km knew) is a surprise (Replan)."""
        # the last asserted change per object (held by / in, on), sent again to a new subscriber
        self.asserted: dict[str, ObjectUpdate] = {}
        self.plan: HierarchicalPlan | None = None
        self.plan_request: Conversation | None = None
        self.requests: deque[Conversation] = deque()  # plan requests not yet taken up
        self.leaves: list[tuple[str, PlanNode]] = []
        self.index = 0
        self.step: Step | None = None
        self.outcome: SWState | None = None
        self.reason: str | None = None
        self.judged: str | None = None  # the plan's last content check, in words: Succeeded's reason
        self.cancel_requested = False
        self.halted_at: str | None = None  # the leaf ag_ex halted
        self.terminating = False  # running the safe-stop HFSM
        self.safe_stop_key: str | None = None
        self.atomic_spans: list[tuple[int, int]] = []
        self.interrupted = False  # the plan ended inside a leaf ag_ex did not finish
        self.retreat: deque[RetreatStep] = deque()
        self.retreat_wait: Conversation | None = None  # the retreat request (or observe)
        self.retreat_reply: tuple[Conversation, bool] | None = None  # its answer once it came
        self.retreated = False  # retreat commands were sent: observe before reporting
        self.withdrawing = False  # in finished: the retreat runs, the final state waits
        self.retreat_note = ""  # what the final state's reason says of the withdrawal
        super().__init__(transport, spec)
        self.reports = self.roles.report(C1, COORDINATE, retry_s=SW_RETRY_S)
        """a_ta's L_SW informs to a_co, sent one at a time, each once a_co confirmed the one
        before (the coordinate role's: services/runtime/roles/confirmed.py)."""
        self.watching = WatchRelay(self._subscribe_watch, self.roles.unsubscribe, self.log)
        """The watch a_km asked for (services/agents/task_executor/watching.py)."""

    def build_fsm(self) -> FSM:
        return FSM(
            [
                Behaviour(
                    "idle",
                    self._idle,
                    # restarted during a plan: report only once the world is observed and
                    # a_km knows it (a held object's pose decides how the next plan begins)
                    terminal=lambda: self.plan is not None and (not self.restored or self.initial_done),
                    doc="await a plan execution request from a_co",
                ),
                Behaviour(
                    "running",
                    self._running,
                    terminal=lambda: self.outcome is not None,
                    on_enter=self._start_plan,
                    doc="execute the plan's HFSM",
                ),
                Behaviour(
                    "finished",
                    self._finished,
                    terminal=lambda: self.plan is None,  # a_co confirmed the final state: done with the plan
                    on_enter=self._enter_finished,
                    doc="await a_co's acknowledgement of the final state",
                ),
            ],
            arcs=[
                Arc("idle", "finished", lambda: self.restored, "restarted during a plan"),
                Arc("idle", "running"),
                Arc("running", "finished"),
                Arc("finished", "idle"),
            ],
        )

    def setup(self) -> None:
        self.roles.subscribe(
            C5,
            FIPA_SUBSCRIBE,
            PowerOns(),
            conversation_id="ta-power-ons",
            retry_s=(1.0, 10.0),
            while_away=False,
        )

    # ---- communicates handled in every state ----
    def _common(self) -> None:
        self.handle_received()

    # a_co's plans (coordinate, participant)
    @handles(COORDINATE, PARTICIPANT, Performative.REQUEST)
    def _on_plan(self, conv: Conversation) -> None:
        # (a_co sends an unanswered plan again when a_ta reappears; a restarted a_ta that kept
        # this very request reports on it: the role does not hand the copy to this handler)
        self.requests.append(conv)

    @handles(COORDINATE, PARTICIPANT, Performative.CANCEL)
    def _on_cancel(self, conv: Conversation) -> None:
        if conv is self.plan_request and self.outcome is None and not self.cancel_requested:
            self.cancel_requested = True
            self._halt()  # first: every millisecond the motion goes on counts
            self._inform_co(SWState.TERMINATING, reason="cancelled by a_co")
        else:  # the plan has ended (the cancel crossed its final state) or is ending
            self.log.info("cancel from a_co for a plan that is not running: nothing to do")

    def _halt(self) -> None:
        """Cancel the C5 request ag_ex runs for the current leaf (FIPA cancel meta-protocol):
        ag_ex halts its motion and answers ``inform`` once the robot is at rest. Nothing when no
        request of the plan runs, it has been answered or cancelled already, or it is an
        observation (nothing moves). The request is no longer sent again nor awaited by its own
        deadline (a halted command must not run again when ag_ex reappears)."""
        step = self.step
        if self.terminating or step is None or step.replan_reason is not None:
            return
        request = step.waiting_for
        command = request.opening.content if request is not None and request.opening is not None else None
        if (
            request is None
            or request.cancels
            or step.reply is not None
            or request.finished
            or isinstance(command, Observe)
        ):
            return
        request.stop_awaiting_replies()
        request.cancel(command, reply_by_s=HALT_REPLY_BY_S)
        self.counters["halts_asked"] += 1
        self.log.info(
            "halting %s: cancel of its %s sent to ag_ex at wall time %.6f",
            step.path,
            command_name(command) if command is not None else "command",
            self.sources.time(),
        )

    # a_km's subscription to environment updates (fipa-subscribe, participant)
    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.SUBSCRIBE)
    def _on_subscribe(self, conv: Conversation) -> None:
        if not isinstance(conv.content, Subscription):
            conv.refuse_with(Performative.REFUSE, "not an L_WM subscription")
            return
        if conv.content.topic == WATCH_TOPIC:
            self.watching.asked(conv, conv.content)
            return
        self.subscription = conv
        conv.reply(Performative.AGREE)
        self._catch_up_subscriber()

    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.CANCEL)
    def _on_unsubscribe(self, conv: Conversation) -> None:
        if conv is self.subscription:
            self.subscription = None
        self.watching.cancelled(conv)
        conv.reply(Performative.INFORM)

    # the robot's power-ons (fipa-subscribe to ag_ex, initiator)
    @handles(FIPA_SUBSCRIBE, INITIATOR, Performative.INFORM)
    def _on_power_on(self, conv: Conversation) -> None:
        """ag_ex tells the power-on of the robot its loop is attached to (at once, then each new
        one): a new one renews what a_km knows before the next plan (``_started_anew``); or a
        frame of its watch, which goes to a_km (``_update_km``) and nowhere else."""
        if isinstance(conv.content, PowerOn):
            self._started_anew(conv.content)
        elif isinstance(conv.content, Observation) and self.watching.is_frame(conv):
            self.watching.frames += 1
            self._update_km(conv.content)

    def _subscribe_watch(self, watch: Watch) -> StandingSubscription:
        """Have the role keep ag_ex's watch asked (fipa-subscribe on C5, beside the power-ons;
        services/agents/task_executor/watching.py)."""
        return self.roles.subscribe(
            C5,
            FIPA_SUBSCRIBE,
            watch,
            conversation_id=self.roles.free_id("ta-watch"),
            reply_by_s=WATCH_REPLY_BY_S,
            retry_s=(1.0, 10.0),
            while_away=False,
        )

    # ag_ex's answers (fipa-request, initiator)
    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_ex_done(self, conv: Conversation) -> None:
        self._ex_answer(conv, True)

    @handles(FIPA_REQUEST, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_ex_failed(self, conv: Conversation) -> None:
        """Refused, failed, not understood, or no answer by the reply-by deadline."""
        self._ex_answer(conv, False)

    def _ex_answer(self, conv: Conversation, ok: bool) -> None:
        # a late answer of the world before keeps neither its robot time nor its observation
        went_back = None if self._of_world_before(conv.content) else self._world_time(conv.content)
        restarted = self._started_anew(conv.content)
        if (
            conv is self.initial_observe or any(conv is c for c in self.initial_asked)
        ) and self._of_world_before(conv.content):
            self.log.info("a late observation of the kitchen before the power cycle ignored")
        elif conv is self.initial_observe or (
            not self.initial_done and ok and any(conv is c for c in self.initial_asked)
        ):
            # an earlier one's late answer will do: the camera may take longer than the short
            # deadline, and asking again each time would never catch up (seen under load)
            self.initial_observe = None
            if isinstance(conv.content, Observation):
                self.initial_done = True
                self.initial_asked.clear()
                self._update_km(conv.content)
            else:
                self._observe_initial()  # deadline passed or failure: ask again
        elif self.step is not None and conv is self.step.waiting_for:
            if self.step.reply is not None:
                # the command's result came first and crossed a_ta's cancel: ag_ex answers
                # that cancel too (failure: the conversation had ended), which tells nothing
                self.log.info(
                    "%s from ag_ex after the result of %s ignored: %s",
                    conv.last.performative.value if conv.last is not None else "answer",
                    self.step.path,
                    conv.reason,
                )
                return
            self.step.went_back = went_back
            self.step.restarted = restarted or (self.distrust_plan and not self.terminating)
            if self.step.restarted:
                self.distrust_plan = False
            if conv.answers_cancel and ok:  # inform: cancelled, the command halted, the robot at rest
                self.step.halted = True
            elif conv.answers_cancel:
                # failure: ag_ex could not halt it, it had ended; its own result says how (none:
                # the cancel had no answer in time, and the command's end is not known)
                result = conv.content
                ok = isinstance(result, CommandResult) and result.ok
                self.log.info(
                    "ag_ex did not halt %s: %s",
                    self.step.path,
                    getattr(result, "reason", None) or conv.reason,
                )
            self.step.reply = (conv, ok)
        elif conv is self.retreat_wait:
            self.retreat_reply = (conv, ok)
        elif conv.last is not None:  # a late reply to a request whose deadline already passed
            self.log.info("late %s from ag_ex ignored", conv.last.performative.value)

    def _world_time(self, answer: object) -> tuple[float, float] | None:
        """Keep the simulated time of ag_ex's ``answer`` (a CommandResult's ``sim_time``, an
        Observation's ``stamp``, s); returns (the latest before, this one) when it went back
        by more than ``WORLD_TIME_SLACK_S``: the world is not the one the steps so far were
        done in (ag_ex restarted on an older or a new world), and what was done may be undone."""
        if isinstance(answer, CommandResult):
            t: float | None = answer.sim_time
        elif isinstance(answer, Observation):
            t = answer.stamp
        else:
            return None
        if t is None:
            return None
        latest, self.world_time = self.world_time, t
        if latest is not None and t < latest - WORLD_TIME_SLACK_S:
            self.log.warning("ag_ex's simulated time went back from %.3f s to %.3f s", latest, t)
            return latest, t
        return None

    def _started_anew(self, answer: object) -> bool:
        """True when ag_ex's ``answer`` names a power-on of the robot never named before (L_EX
        ``CommandResult.world``, L_SD ``Observation.world``, or ag_ex's L_EX ``PowerOn`` in
        a_ta's subscription): the robot was power-cycled, its kitchen started anew. Then what
        a_ta asserted is forgotten, a_km's next observation renews its world (``renew_km``) and
        the scene is observed at once, so that a_km knows the new kitchen before the next plan
        is made; the next leaf answered ends its plan in Replan (``distrust_plan``): that plan
        may be of the kitchen before. A late answer from a loop of a world before (a command
        the power cycle ended ``stopped``) names none new."""
        world = answer.world if isinstance(answer, CommandResult | Observation | PowerOn) else ""
        if not world or world == self.world or world in self.worlds_before:
            return False  # none named, the same, or a late answer of a loop of a world before
        before, self.world = self.world, world
        if before is None:
            return False
        self.worlds_before.add(before)
        self.counters["world_restarts"] += 1
        self.log.warning(
            "ag_ex's robot was power-cycled (world %s, before %s): its kitchen started anew; "
            "a_km's picture of it is renewed from a fresh observation",
            world,
            before,
        )
        self.asserted.clear()
        self.renew_km = True
        self.distrust_plan = True
        self.initial_done = False
        self._observe_initial()
        return True

    def _catch_up_subscriber(self) -> None:
        """A new subscription (a_km started, or restarted and maybe missed updates that were
        in flight: fipa-subscribe informs are not acknowledged) gets the world anew: first the
        last symbolic change a_ta asserted of each object in this process's life (held by a
        hand, or in/on a place), then a fresh observation (poses and content)."""
        if self.asserted:
            self._inform_km(WorldUpdate(stamp=-1.0, objects=tuple(self.asserted.values())))
        if self.initial_done:
            self.initial_done = False  # observe again for this subscriber
        self._observe_initial()

    def _observe_initial(self) -> None:
        if self.initial_done or self.initial_observe is not None:
            return
        # ag_ex may not listen yet at start-up: sent again at once when its liveliness token
        # appears, and asked anew after a short deadline rather than a long one
        self.initial_observe = self._request_observe(reply_by_s=INITIAL_OBSERVE_RETRY_S)
        self.initial_asked = [*self.initial_asked[-(INITIAL_OBSERVE_KEPT - 1) :], self.initial_observe]

    def _request_observe(
        self, objects: tuple[str, ...] = (), reply_by_s: float = OBSERVE_REPLY_BY_S
    ) -> Conversation:
        """Ask ag_ex for an L_SD observation of ``objects`` (``()``: the whole scene); the
        request is sent again at once when ag_ex's liveliness token reappears, and fails locally
        after ``reply_by_s`` (s)."""
        return self._request(Observe(objects=objects), reply_by_s, RESEND_ON_RETURN)

    def _request(self, command: msgspec.Struct, reply_by_s: float, retry_s: float | None) -> Conversation:
        """Request ``command`` of ag_ex (fipa-request on C5)."""
        return self.roles.open(C5, FIPA_REQUEST, command, reply_by_s=reply_by_s, retry_s=retry_s)

    def _of_world_before(self, answer: object) -> bool:
        """True when ag_ex's ``answer`` comes from a power-on before the robot's last one (a
        command the power cycle ended, answered late by the old loop): it describes a kitchen
        that no longer exists, at a robot time that is no longer the robot's."""
        world = answer.world if isinstance(answer, CommandResult | Observation | PowerOn) else ""
        return bool(world) and world in self.worlds_before

    def _update_km(self, obs: Observation) -> None:
        """Inform a_km of what ``obs`` saw (:func:`observed_update`); the first observation of a
        robot that was power-cycled renews a_km's world (``renew_km``). An observation of the
        kitchen before the power cycle is not sent: its robot time (later than the new kitchen's)
        would make a_km take every observation of the new one for stale."""
        if self._of_world_before(obs):
            self.counters["observations_of_world_before"] += 1
            self.log.info(
                "an observation of the kitchen before the power cycle (world %s) not sent to a_km", obs.world
            )
            return
        update = observed_update(obs, self.sources.time())
        if self.renew_km and self.subscription is not None and obs.world in ("", self.world):
            update = msgspec.structs.replace(update, renews=True)
            self.renew_km = False
        self._inform_km(update)

    def _inform_km(self, update: WorldUpdate) -> None:
        if self.subscription is None:
            self.log.warning("no subscription from a_km yet; update at %.2f s not sent", update.stamp)
            return
        self.subscription.reply(Performative.INFORM, update)

    def _inform_co(self, state: SWState, step: str | None = None, reason: str | None = None) -> None:
        """Inform a_co of the plan's supervised-worker state; the coordinate role sends the
        informs one at a time, each after a_co confirmed the previous one (paper Figure 8: loop
        of inform and confirm), a terminal state being the plan's last."""
        if self.plan_request is None or self.plan is None:
            return
        status = SWStatus(state=state, plan_id=self.plan.plan_id, step=step, reason=reason)
        self.reports.inform(self.plan_request, status, final=state in TERMINAL_SW_STATES)

    # ---- restarts (the role keeps the plan's conversation: docs/recovery.md) ----
    def persist(self) -> None:
        """Note the leaf step in the plan's conversation (:class:`PlanNote`), then keep it
        (:meth:`Agent.persist`)."""
        conv = self.plan_request
        if conv is not None:
            step = self.step.path if self.step is not None else None
            running = self.engine.state == "running"
            between = running and self.outcome is None and 0 <= self.index < len(self.leaves)
            if step is None and between:
                # between two leaves (e.g. after a set-down's ``put``, an Assert with no motion):
                # the next one, so that a restart finishes the set-down (seen: killed there, the
                # restarted a_ta knew no step, the hand stayed beside the bowl and the next plan's
                # pour ran into it)
                step = self.leaves[self.index][0]
            note = PlanNote(step=step, outcome=self.outcome, reason=self.reason)
            if note != conv.data:
                conv.data = note
        super().persist()

    def on_restored(self, conversation: Conversation) -> None:
        """Report on the plan a previous a_ta ran (see the module docstring). Raises TypeError
        for a kept request without a plan (the role drops it)."""
        plan = conversation.opening_content(HierarchicalPlan)
        kept = conversation.data if isinstance(conversation.data, PlanNote) else PlanNote()
        self.plan, self.plan_request = plan, conversation
        if kept.outcome is not None:
            self.outcome, self.reason = kept.outcome, kept.reason
        else:
            where = f" in {kept.step}" if kept.step else ""
            self.outcome = SWState.REPLAN
            self.reason = f"a_ta restarted{where}; the robot held position"
            self.leaves = plan.root.leaves()
            self.atomic_spans = plan.root.atomic_spans()
            paths = [path for path, _ in self.leaves]
            if kept.step in paths:  # not so for a leaf of a safe-stop HFSM
                self.index, self.interrupted = paths.index(kept.step), True
        self.restored = True
        self.log.info("restarted during plan %s: reporting %s", plan.plan_id, self.outcome.value)

    def peer_changed(self, peer: str, alive: bool) -> None:
        """ag_ex came back (restarted, attached to the running world) while a tilt it
        was running, or a command a_ta was having it halt, had no answer: neither can be sent
        again (a tilt is relative; a halted command must not run on), so the world is observed
        and Replan reported. Other commands are sent again by the runtime. a_km gone, the
        watch it asked for ends."""
        if peer == "a_km" and not alive:
            self.watching.stop("a_km lost")
        step = self.step
        if peer != "ag_ex" or not alive or step is None or step.waiting_for is None or step.reply:
            return
        action = step.node.action
        tilt = isinstance(action, Execute) and isinstance(action.command, Tilt)
        halting = bool(step.waiting_for.cancels)
        if (tilt or halting) and self.outcome is None:
            step.waiting_for.forget()
            during = "the halt" if halting else "the tilt"
            self._surprise(step, f"{step.path}: ag_ex restarted during {during}")

    # ---- idle ----
    def _idle(self) -> None:
        self._common()
        if self.plan is not None or not self.requests:
            return
        conv = self.requests.popleft()
        plan = conv.opening.content if conv.opening is not None else None
        if isinstance(plan, HierarchicalPlan):
            self.plan, self.plan_request = plan, conv
            self.outcome, self.cancel_requested = None, False
        else:
            conv.refuse_with(Performative.REFUSE, "no hierarchical plan in the request")

    # ---- running ----
    def _start_plan(self) -> None:
        assert self.plan is not None
        self.leaves = self.plan.root.leaves()
        self.atomic_spans = self.plan.root.atomic_spans()
        self.index = 0
        self.step = None
        self.outcome = None
        self.reason = None
        self.judged = None
        self.cancel_requested = False
        self.halted_at = None
        self.terminating = False
        self.log.info("plan %s: %d leaf states", self.plan.plan_id, len(self.leaves))
        self._inform_co(SWState.RUNNING)

    def _in_atomic(self) -> bool:
        """True while the next leaf belongs to an atomic state already entered."""
        return any(start < self.index < end for start, end in self.atomic_spans)

    def _running(self) -> None:
        self._common()
        step = self.step
        if step is not None and step.waiting_for is not None:
            waiting_for = step.waiting_for
            if step.reply is None:
                return
            reply, ok = step.reply
            step.reply = None
            self._complete(reply, ok)
            if self.outcome is not None or (
                self.step is not None and self.step.waiting_for is not waiting_for
            ):
                return  # ended, or the step asked ag_ex something more (a look after a surprise)
        if self.cancel_requested and not self.terminating and not self._in_atomic():
            self._begin_safe_stop()
        if self.index >= len(self.leaves):
            assert self.plan is not None
            if self.terminating:
                self._end(SWState.PREEMPTED, self._safe_stop_summary())
            elif self.plan.complete:
                self._end(SWState.SUCCEEDED, self.judged)
            else:
                self._end(SWState.REPLAN, "the plan ends with sensing; a new plan is needed")
            return
        path, node = self.leaves[self.index]
        self.step = Step(path, node)
        self._inform_co(SWState.TERMINATING if self.terminating else SWState.RUNNING, step=path)
        self._begin(self.step)
        if self.cancel_requested:
            # the cancel came between two leaves of an atomic state: the leaf just sent is halted
            # at once (ag_ex halts the robot as it stands, a tilted jar turned upright)
            self._halt()

    def _begin_safe_stop(
        self, key: str | None = None, first: list[tuple[str, PlanNode]] | None = None
    ) -> None:
        """Switch to the safe-stop HFSM named ``key`` (default: the one the next leaf names;
        paper §3.2: put what is held down safely before reporting Preempted), after the leaves
        ``first`` (what makes the hands safe after a halt; ``_after_halt``); no safe stop: stop
        where the robot is."""
        assert self.plan is not None
        self.terminating = True
        if first is None:
            key = self.leaves[self.index][1].on_cancel if self.index < len(self.leaves) else None
        first = first or []
        stop = self.plan.safe_stops.get(key) if key is not None else None
        self.safe_stop_key = key if stop is not None else None
        leaves = stop.leaves() if stop is not None else []
        spans = stop.atomic_spans() if stop is not None else []
        self.leaves = first + leaves
        self.atomic_spans = ([(0, len(first))] if first else []) + [
            (a + len(first), b + len(first)) for a, b in spans
        ]
        self.index = 0
        self.log.info(
            "terminating: %d steps to make the hands safe, safe stop %s (%d steps)",
            len(first),
            key or "none",
            len(leaves),
        )

    def _after_halt(self, reply: Conversation) -> None:
        """ag_ex halted the current leaf for a_co's cancel (its answer ``reply``): run, from
        where the robot stopped, what makes it safe (module docstring), as the safe stop."""
        assert self.plan is not None
        path, node = self.leaves[self.index]
        self.halted_at = path
        result = reply.content
        at = f" at {result.sim_time:.2f} s" if isinstance(result, CommandResult) and result.sim_time else ""
        self.log.info("%s halted%s (%s)", path, at, HALTED)
        self.step = None
        span = next(((a, b) for a, b in self.atomic_spans if a <= self.index < b), None)
        first: list[tuple[str, PlanNode]] = []
        key = node.on_cancel
        command = node.action.command if isinstance(node.action, Execute) else None
        if span is not None and not any(
            isinstance(n.action, Execute) and isinstance(n.action.command, Tilt)
            for _, n in self.leaves[slice(*span)]
        ):
            # a take, a set-down: the rest of it, the halted leaf again (its targets are absolute)
            first = self.leaves[self.index : span[1]]
            key = self.leaves[span[1]][1].on_cancel if span[1] < len(self.leaves) else None
        elif isinstance(command, MoveJoints) and TORSO_JOINT in command.positions and key is not None:
            # a torso turn, halted half-way: the safe stops are planned for the torso where a
            # leaf begins or ends, so it turns back where the plan last put it, else on to its
            # target (then the next leaf's safe stop)
            before = self._torso_before(self.index)
            if before is not None:
                back = MoveJoints(positions={TORSO_JOINT: before}, duration=command.duration)
                first = [(f"{path}/turn_back", PlanNode(name="turn_back", action=Execute(command=back)))]
            else:
                first = self.leaves[self.index : self.index + 1]
                key = self.leaves[self.index + 1][1].on_cancel if self.index + 1 < len(self.leaves) else None
        self._begin_safe_stop(key, first)

    def _torso_before(self, index: int) -> float | None:
        """The torso angle (rad) the plan's last torso turn before leaf ``index`` commanded
        (None: the plan turned it before none)."""
        for _, node in reversed(self.leaves[:index]):
            command = node.action.command if isinstance(node.action, Execute) else None
            if isinstance(command, MoveJoints) and TORSO_JOINT in command.positions:
                return command.positions[TORSO_JOINT]
        return None

    def _safe_stop_summary(self) -> str:
        put = [
            f"the {n.action.subject} down {'in' if n.action.relation == 'in' else 'on'} the {n.action.object}"
            for _, n in self.leaves
            if isinstance(n.action, Assert) and n.action.relation in ("on", "in")
        ]
        said = "cancelled by a_co" + (f"; halted {self.halted_at}" if self.halted_at else "")
        if not put:
            return f"{said}; nothing was held"
        return f"{said}; put {' and '.join(put)}"

    def _begin(self, step: Step) -> None:
        action = step.node.action
        if isinstance(action, Execute):
            cmd = action.command
            step.waiting_for = self._request(
                cmd,
                expected_s(cmd) * 2 + COMMAND_MARGIN_S,
                # a tilt is relative: done again from where the last one stopped it over-tilts
                None if isinstance(cmd, Tilt) else RESEND_ON_RETURN,
            )
        elif isinstance(action, Perceive | CheckContent):
            objects = action.objects if isinstance(action, Perceive) else (action.container,)
            self._observe(step, objects)
        elif isinstance(action, Assert):
            self._assert(action)
            self.index += 1
            self.step = None
        else:
            self.index += 1  # a composite state with no leaves
            self.step = None

    def _observe(self, step: Step, objects: tuple[str, ...]) -> None:
        step.waiting_for = self._request_observe(objects)

    def _assert(self, action: Assert) -> None:
        if action.relation == "heldBy":
            change = ObjectUpdate(name=action.subject, held_by=action.object)
        else:
            change = ObjectUpdate(
                name=action.subject, location=action.object, relation=action.relation, held_by=""
            )
        self.asserted[action.subject] = change  # the last one describes the object fully
        self._inform_km(WorldUpdate(stamp=-1.0, objects=(change,)))

    def _complete(self, reply: Conversation, ok: bool) -> None:
        """Go on after ag_ex answered the step's request (``ok`` for ``inform``; otherwise
        refuse, failure, not-understood or no answer by the deadline): apply a_ta's verdict
        (services/agents/task_executor/verdict.py ``judge``)."""
        step = self.step
        assert step is not None
        said = reply.last.performative.value if reply.last is not None else "failure"
        verdict = judge(step, Answer(ok, reply.content, said, reply.reason), self.terminating)
        for note in verdict.notes:
            self.log.info("%s", note)
        if verdict.observed is not None:
            self._update_km(verdict.observed)
        if verdict.do is Do.NEXT and isinstance(step.node.action, CheckContent):
            self.judged = verdict.reason  # what the content check counted: Succeeded's reason
        self._apply(step, verdict, reply)

    def _apply(self, step: Step, verdict: Verdict, reply: Conversation) -> None:
        """Do what ``verdict`` says of ``step`` (:class:`~.verdict.Do`); ``reply`` is ag_ex's
        answer."""
        do = verdict.do
        if do is Do.NEXT:
            self.index += 1
            self.step = None
        elif do is Do.HALTED:
            self._after_halt(reply)
        elif do is Do.OBSERVE_AGAIN:
            step.second_view = 2
            self._observe(step, verdict.objects)
        elif do is Do.LOOK:
            assert verdict.look_at is not None
            self.log.info("%s: %s: a second view", step.path, verdict.reason)
            step.second_view = 1
            step.first_look = verdict.observed
            step.waiting_for = self._request(LookAt(point=verdict.look_at), LOOK_REPLY_BY_S, RESEND_ON_RETURN)
        elif do is Do.SURPRISE:
            if verdict.interrupted:
                self.interrupted = True
            self._surprise(step, verdict.reason or "")
        else:
            self._end(_ENDS[do], verdict.reason)

    def _surprise(self, step: Step, reason: str) -> None:
        """The world differs from the plan: observe the whole scene (a_km learns it), then
        report Replan with ``reason``."""
        self.log.info("surprise: %s", reason)
        step.replan_reason = reason
        self._observe(step, ())

    def _end(self, state: SWState, reason: str | None) -> None:
        self.outcome, self.reason = state, reason
        self.log.info("plan ends %s %s", state.value, reason or "")

    # ---- finished ----
    def _enter_finished(self) -> None:
        """Make the hands safe after an interrupted take (``undo_take``) or set-down
        (``finish_set_down``; services/agents/task_executor/retreat.py), else
        report the final state at once."""
        commands: tuple[RetreatStep, ...] = ()
        if self.interrupted:
            commands = undo_take(self.leaves, self.atomic_spans, self.index)
            self.retreat_note = "the hand was opened and withdrawn along its approach"
            if not commands:
                commands = finish_set_down(self.leaves, self.atomic_spans, self.index)
                self.retreat_note = "the set-down was finished and the hand moved clear"
        self.interrupted = False
        self.retreat = deque(commands)
        self.retreated = False
        self.withdrawing = bool(commands)
        if commands:
            self.log.info(
                "%s was interrupted: making the hand safe (%d steps) before reporting",
                self.leaves[self.index][0],
                len(commands),
            )
        else:
            self._report_final()

    def _retreat_step(self) -> None:
        """One step of the withdrawal: await ag_ex's answer, send the next command; after the
        commands the scene is observed and a_km informed; then the final state is reported."""
        if self.retreat_wait is not None:
            if self.retreat_reply is None:
                return
            reply, ok = self.retreat_reply
            self.retreat_wait = self.retreat_reply = None
            said = reply.last.performative.value if reply.last is not None else "failure"
            if isinstance(reply.content, Observation):
                self._update_km(reply.content)
            elif not ok:
                why = getattr(reply.content, "reason", None) or said
                self.log.warning("withdrawal stopped: ag_ex answered %s (%s)", said, why)
                self.retreat.clear()
                self.retreat_note = f"withdrawing the hand failed ({why})"
        while self.retreat:
            cmd = self.retreat.popleft()
            if isinstance(cmd, Assert):  # a_km learns where the object was put; no motion
                self._assert(cmd)
                continue
            self.retreat_wait = self._request(cmd, expected_s(cmd) * 2 + COMMAND_MARGIN_S, RESEND_ON_RETURN)
            self.retreated = True
            return
        if self.retreated:  # the hand moved: a_km learns the scene as it is now
            self.retreated = False
            self.reason = f"{self.reason}; {self.retreat_note}" if self.reason else self.retreat_note
            self.retreat_wait = self._request_observe()
            return
        self.withdrawing = False
        self._report_final()

    def _report_final(self) -> None:
        assert self.outcome is not None
        self._inform_co(self.outcome, reason=self.reason)

    def _finished(self) -> None:
        self._common()
        if self.withdrawing:
            self._retreat_step()
            return
        if self.reports.final_confirmed(self.plan_request):
            if self.plan_request is not None:
                self.plan_request.data = None  # nothing to keep any more
                self.reports.done_with(self.plan_request)
            self.plan = None
            self.plan_request = None
            self.restored = False
