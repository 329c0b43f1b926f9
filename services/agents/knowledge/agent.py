"""a_km — the knowledge manager (paper §5.5, Table 5, Figure 11c). The manual: docs/agents.md
"a_km"; its restarts: docs/recovery.md.

FSM states: idle (wait for a query from a_pl, a_ta or a_hi, or an observation),
questionAnswering (one query, hypothetical queries of §5.7 included: ``inform-ref`` with an
L_WM Answer to ``query-ref``, ``inform`` to ``query-if``; ``refuse`` with the reason for a
query a_km does not answer, ``failure`` with the reason for one it cannot), knowledgeSaving
(apply one observation or asserted change; an update that ``renews`` the world replaces what
a_km believed by the kitchen's initial knowledge and that observation, ``WorldModel.renew``).

It keeps a fipa-subscribe with a_ta open for environment updates (C6,
services/runtime/roles/subscriptions.py), and serves fipa-subscribe (FIPA SC00035) to scene changes
(L_WM ``SceneSubscription``, ``SceneChange``; services/agents/knowledge/scene_watch.py) on every
channel where the specification makes it the participant; those are not kept across its
restart. A scene subscription with ``within_s`` (tell a change within that long) makes a_km ask
a_ta for a watch while it lasts (a second fipa-subscribe on C6, ``Subscription`` topic
``watch``: services/agents/knowledge/watch_demand.py); a_ta's watched frames then come as
observations. Started with kept knowledge, it holds queries until a_ta's first observation, at most
``HOLD_QUERIES_S``. The knowledge is stored in ``ROCO_KM_STORE``, else
``<ROCO_RUN_DIR>/km_store``, else memory only (services/agents/knowledge/world_model.py);
:meth:`KnowledgeManager.close` (called by ``services.runtime.main``) flushes and releases it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from services.agents.knowledge import scene_watch
from services.agents.knowledge.scene_watch import Watch
from services.agents.knowledge.watch_demand import WatchDemand, period_for
from services.agents.knowledge.world_model import KnowledgeError, UnsupportedQuery, WorldModel
from services.runtime.agent import FSM, Agent, Arc, Behaviour, Transport
from services.runtime.roles import (
    EVERY_CHANNEL,
    INITIATOR,
    PARTICIPANT,
    Conversation,
    ServedSubscription,
    StandingSubscription,
    handles,
    initiator,
    participant,
)
from services.spec.model import SystemSpec
from services.spec.names import C6, FIPA_QUERY, FIPA_SUBSCRIBE, L_WM
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_wm import (
    GraspQuery,
    HypotheticalQuery,
    ObjectInfo,
    ObjectQuery,
    PlacementQuery,
    PourQuery,
    SceneChange,
    SceneQuery,
    SceneSubscription,
    SparqlQuery,
    Subscription,
    WorldUpdate,
)
from shared.settings import Settings

QUERY_TYPES = (SparqlQuery, ObjectQuery, SceneQuery, GraspQuery, PlacementQuery, PourQuery, HypotheticalQuery)
SUBSCRIBE_RETRY_S = 2.0
HOLD_QUERIES_S = 10.0
"""Longest a restarted a_km (kept knowledge) holds queries for a_ta's first observation (s)."""
STORE_IN_RUN_DIR = "km_store"


def store_path(environ: Mapping[str, str] | None = None) -> Path | None:
    """The knowledge store's directory from the environment (default ``os.environ``):
    ``ROCO_KM_STORE``; else ``<ROCO_RUN_DIR>/km_store``; else None (in memory). Empty values
    count as unset."""
    read = Settings.from_env(environ, only=("km_store", "run_dir"))
    if read.km_store is not None:
        return read.km_store
    return read.run_dir / STORE_IN_RUN_DIR if read.run_dir is not None else None


@dataclass(frozen=True)
class Query:
    """A query to answer: its conversation and the performative that answers it (FIPA
    SC00027: ``inform`` to query-if, ``inform-ref`` to query-ref)."""

    conversation: Conversation
    answer: Performative


class KnowledgeManager(Agent):
    name = "a_km"
    environment: StandingSubscription
    """The subscription to a_ta's environment updates, opened in :meth:`setup`."""
    ROLES = (
        # every channel that asks a_km L_WM queries (C4, C6, C7, and any the specification adds)
        participant(EVERY_CHANNEL, FIPA_QUERY, L_WM),
        # every channel that subscribes to changes of the scene (any the specification adds)
        participant(EVERY_CHANNEL, FIPA_SUBSCRIBE, L_WM),
        initiator(C6, FIPA_SUBSCRIBE, L_WM, reply_by_s=SUBSCRIBE_RETRY_S, resubscribes=True),
    )

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
        """a_km's memory (paper §3.2: the agent's internal memory), then the runtime's
        (:class:`~services.runtime.agent.Agent`), which builds the FSM, then what needs the
        runtime: the knowledge base in the run's store (services/agents/knowledge/world_model.py)
        and the streams of scene changes. Raises StoreError (a ValueError) when the store
        cannot be opened."""
        self.work: deque[Query | WorldUpdate] = deque()  # queries and observations, as they came
        self.current: Query | WorldUpdate | None = None  # the one being answered or saved
        self.held: deque[Query] = deque()  # queries waiting for the first observation
        self.watches: dict[str, Watch] = {}  # the agreed scene subscription of each channel
        super().__init__(transport, spec)
        path = store_path()
        # the knowledge base; StoreError (a ValueError) when the store cannot be opened
        self.world = WorldModel(path)
        self.log.info(
            "knowledge in %s: %d triples%s",
            path or "memory",
            len(self.world),
            " (kept from before)" if self.world.kept else "",
        )
        # until when queries wait for the first observation after a restart (the agent's
        # monotonic s; None: they do not, the knowledge base is new or the wait is over)
        self.hold_until: float | None = self.sources.monotonic() + HOLD_QUERIES_S if self.world.kept else None
        # changes of the scene, served on every channel that subscribes to them: one stream per
        # channel; a_km informs only an agreed subscription, so nothing is kept while none is
        self.scene_streams: dict[str, ServedSubscription[SceneChange]] = {
            decl.channel: self.roles.serve(
                decl.channel,
                FIPA_SUBSCRIBE,
                unsent=list,
                about=lambda change: change.object,
                kept_each=1,
                kept_in_all=1,
                dropped="scene_changes_dropped",
            )
            for decl in self.roles.declared
            if decl.protocol == FIPA_SUBSCRIBE and decl.role == PARTICIPANT
        }
        self.watch_demand = WatchDemand(self._subscribe_watch, self.roles.unsubscribe, self.log)
        """The robot's watch a_km asks of a_ta while a subscriber needs it (watch_demand.py)."""

    def build_fsm(self) -> FSM:
        return FSM(
            [
                Behaviour(
                    "idle",
                    self._idle,
                    terminal=lambda: self.current is not None,
                    doc="await a query or an observation; send the queued changes of the scene",
                ),
                Behaviour(
                    "questionAnswering",
                    self._answer,
                    terminal=lambda: True,
                    waits=False,
                    doc="reason over the knowledge base; reply to the query",
                ),
                Behaviour(
                    "knowledgeSaving",
                    self._save,
                    terminal=lambda: True,
                    waits=False,
                    doc="update the knowledge base with an observation",
                ),
            ],
            arcs=[
                Arc("idle", "questionAnswering", lambda: isinstance(self.current, Query), "query"),
                Arc("idle", "knowledgeSaving", lambda: isinstance(self.current, WorldUpdate), "observation"),
                Arc("questionAnswering", "idle"),
                Arc("knowledgeSaving", "idle"),
            ],
        )

    def setup(self) -> None:
        self.environment = self.roles.subscribe(
            C6,
            FIPA_SUBSCRIBE,
            Subscription("environment"),
            conversation_id="km-environment",
            retry_s=(0.0, 0.0),
            at_start=True,
            while_away=False,
        )

    def close(self) -> None:
        """Flush and release the knowledge store (the hook ``services.runtime.main`` calls after
        :meth:`run` ends). Idempotent."""
        self.world.close()

    # ---- the subscription to a_ta's environment updates (fipa-subscribe, initiator) ------
    @handles(FIPA_SUBSCRIBE, INITIATOR, Performative.INFORM)
    def _on_update(self, conv: Conversation) -> None:
        if isinstance(conv.content, WorldUpdate):
            self.work.append(conv.content)

    # ---- queries from a_pl and a_ta (fipa-query, participant) -----------------------------
    @handles(FIPA_QUERY, PARTICIPANT, Performative.QUERY_REF)
    def _on_query_ref(self, conv: Conversation) -> None:
        self._take_query(Query(conv, Performative.INFORM_REF))

    @handles(FIPA_QUERY, PARTICIPANT, Performative.QUERY_IF)
    def _on_query_if(self, conv: Conversation) -> None:
        self._take_query(Query(conv, Performative.INFORM))

    @handles(FIPA_QUERY, PARTICIPANT, Performative.CANCEL)
    def _on_query_cancel(self, conv: Conversation) -> None:
        """Queries are answered as they come: only a held or queued one can still be dropped."""
        for waiting in (self.held, self.work):
            for query in list(waiting):
                if isinstance(query, Query) and query.conversation is conv:
                    waiting.remove(query)
                    conv.reply(Performative.INFORM)
                    return
        conv.refuse_with(Performative.FAILURE, "nothing to cancel: the query was already answered")

    # ---- changes of the scene (fipa-subscribe, participant) --------------------------------
    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.SUBSCRIBE)
    def _on_scene_subscribe(self, conv: Conversation) -> None:
        sub = conv.content
        channel = conv.decl.channel
        if not isinstance(sub, SceneSubscription):
            what = type(sub).__name__ if sub is not None else "no content"
            conv.refuse_with(Performative.REFUSE, f"not a SceneSubscription: {what}")
            return
        why = scene_watch.problems(sub)
        others = [c for c in self._watching() if c != channel]
        if not why and len(others) >= scene_watch.MAX_SUBSCRIBERS:
            why = [f"a_km serves at most {scene_watch.MAX_SUBSCRIBERS} scene subscriptions at once"]
        if why:
            self.log.info("refused the scene subscription of %s: %s", conv.peer, "; ".join(why))
            conv.refuse_with(Performative.REFUSE, "; ".join(why))
            return
        watch = Watch(conv.conversation_id, sub)
        watch.start(self._known(None if not sub.objects else sub.objects))
        self.watches[channel] = watch
        self.scene_streams[channel].agree(conv)
        self._watching()  # a subscriber that needs changes quickly: the robot watches
        self.log.info(
            "%s subscribed to changes of %s (%s)",
            conv.peer,
            ", ".join(sub.objects) or "the scene",
            conv.conversation_id,
        )

    def _watching(self) -> dict[str, Watch]:
        """The agreed scene subscriptions still open, by channel (an ended one is forgotten);
        the robot's watch asked for as they need it (watch_demand.py)."""
        for channel, watch in list(self.watches.items()):
            conv = self.scene_streams[channel].conversation
            if conv is None or conv.conversation_id != watch.conversation_id:
                del self.watches[channel]
                self.log.info("the scene subscription %s on %s ended", watch.conversation_id, channel)
        self.watch_demand.need(period_for(w.subscription for w in self.watches.values()))
        return self.watches

    def _subscribe_watch(self, subscription: Subscription) -> StandingSubscription:
        """Have the role keep the robot's watch asked of a_ta (fipa-subscribe on C6, beside the
        environment subscription; watch_demand.py)."""
        return self.roles.subscribe(
            C6,
            FIPA_SUBSCRIBE,
            subscription,
            conversation_id=self.roles.free_id("km-watch"),
            retry_s=(1.0, 10.0),
            while_away=False,
        )

    def _known(self, names: tuple[str, ...] | list[str] | None) -> list[ObjectInfo]:
        """What a_km knows of the objects ``names`` (None: every physical object); an object it
        knows nothing of is left out."""
        out: list[ObjectInfo] = []
        for name in self.world.physical_objects() if names is None else names:
            try:
                out.append(self.world.object_info(name))
            except KnowledgeError:
                continue
        return out

    def _tell_changes(self, update: WorldUpdate) -> None:
        """Queue, for every scene subscription, the changes ``update`` (just saved) made."""
        watches = self._watching()
        if not watches:
            return
        names = None if update.renews else sorted({o.name for o in update.objects})
        now = self._known(names)
        for watch in watches.values():
            before = watch.dropped_in_all
            watch.compare(now, update.stamp, update.seen_at)
            if watch.dropped_in_all > before:
                self.counters["scene_changes_dropped"] += watch.dropped_in_all - before
                if before == 0:
                    self.log.warning(
                        "scene subscription %s: changes came faster than they were sent, the "
                        "oldest dropped (at most %d kept)",
                        watch.conversation_id,
                        watch.subscription.queue,
                    )

    def _send_changes(self) -> None:
        """Send each scene subscription its next queued changes (at most
        :data:`~services.agents.knowledge.scene_watch.BURST` each)."""
        for channel, watch in self._watching().items():
            for change in watch.due():
                self.scene_streams[channel].inform(change)
                self.counters["scene_changes"] += 1

    def _take_query(self, query: Query) -> None:
        if self._holding():
            if not self.held:
                self.log.info("restarted: holding queries until a_ta's first observation")
            self.held.append(query)
        else:
            self.work.append(query)

    def _holding(self) -> bool:
        """True while queries wait for the first observation after a restart (see the module
        docstring); logs once when the bound ends the wait."""
        if self.hold_until is None:
            return False
        if self.sources.monotonic() < self.hold_until:
            return True
        self.hold_until = None
        if self.held:
            self.log.warning(
                "no observation from a_ta within %.0f s of the restart: answering %d held "
                "queries from the kept knowledge",
                HOLD_QUERIES_S,
                len(self.held),
            )
        return False

    # ---- the behaviours ---------------------------------------------------------------------
    def _idle(self) -> None:
        self.current = None
        self._send_changes()
        if self.held and not self._holding():
            self.current = self.held.popleft()
            return
        self.handle_received()
        if self.work:
            self.current = self.work.popleft()

    def _answer(self) -> None:
        current = self.current
        assert isinstance(current, Query)
        conv = current.conversation
        query = conv.opening.content if conv.opening is not None else None
        self.counters["queries"] += 1
        if not isinstance(query, QUERY_TYPES):
            what = type(query).__name__ if query is not None else "no content"
            self.log.info("refused a %s from %s: not an L_WM query", what, conv.peer)
            conv.refuse_with(Performative.REFUSE, f"not an L_WM query: {what}")
            return
        try:
            answer = self.world.answer(query)
        except UnsupportedQuery as exc:
            self.log.info("refused %s: %s", type(query).__name__, exc)
            conv.refuse_with(Performative.REFUSE, str(exc))
            return
        except KnowledgeError as exc:
            self.log.info("query %s failed: %s", type(query).__name__, exc)
            conv.refuse_with(Performative.FAILURE, str(exc))
            return
        except Exception as exc:  # a fault must not leave the querier waiting for its deadline
            self.log.exception("query %s raised", type(query).__name__)
            self.counters["query_errors"] += 1
            conv.refuse_with(Performative.FAILURE, f"internal error: {type(exc).__name__}: {exc}")
            return
        conv.reply(current.answer, answer)

    def _save(self) -> None:
        update = self.current
        assert isinstance(update, WorldUpdate)
        if update.renews:  # a_ta: the robot was power-cycled, its kitchen started anew
            n = self.world.renew(update)
            self.counters["renewals"] += 1
            self.log.warning(
                "the robot was power-cycled: what was known of the world dropped, the initial "
                "kitchen taken with the observation at t=%.2f",
                update.stamp,
            )
        else:
            n = self.world.apply(update)
        self.counters["updates"] += 1
        self.counters["stale_poses"] = self.world.stale_poses
        self.counters["unstamped_poses"] = self.world.unstamped_poses
        self.counters["rejected_changes"] = self.world.rejected_changes
        self.log.info("saved %d object updates (t=%.2f)", n, update.stamp)
        self._tell_changes(update)
        if self.hold_until is not None and update.stamp >= 0:  # an observation
            self.hold_until = None
            if self.held:
                self.log.info("observation saved: answering %d held queries", len(self.held))
