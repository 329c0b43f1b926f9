"""Run a scenario against a fleet of processes (router, recorder, one process per agent), as
``roco run`` and ``roco scenario`` do: start everything, wait for a_km's initial knowledge
(paper Table 7), carry out the steps when their triggers hold, wait for every command's
outcome, stop everything. The run folder keeps the traffic, logs and ``run.json``.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import queue
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import aiohttp
import msgspec
import zenoh

from services.fleet.launcher import GATEWAY, ROS2, Fleet, LaunchError, free_port
from services.gateway.http_mtp import MTPError
from services.gateway.platform import ForeignPlatform
from services.recorder.sync import sync
from services.runtime import keys
from services.runtime.counters import ask_counters, save_counters
from services.runtime.faults import FaultEvent
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from services.runtime.raised import log_of, raised_by_agent, raised_text
from services.runtime.reports import MissedOutcomes, ReportFilter, follow_reports
from services.runtime.run_folder import RunCommand, RunInfo, write_run_info
from services.runtime.session import open_client
from services.scenario.model import Fault, Scenario, Step
from services.spec.model import DEFAULT_SPEC, SystemSpec, channel_between, default_spec, load, spec_path
from shared.fipa_codec import Communicate, DecodeError, Performative, decode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.languages.l_hc import SentenceReport
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.languages.l_wm import WorldUpdate

Echo = Callable[[str], None]
KINDS = frozenset(k.value for k in ReportKind)
"""The kinds of report a ``SentenceReport`` may carry (services/runtime/human.py)."""
SUMMARY_NOTICES = 20
"""The most notices to the person a run's summary lists (the last ones)."""
MAX_CRASHES = 3
"""Times a process (an agent, the recorder, a router) that exits by itself is started again
during a run before the run ends."""


class Hosting(Protocol):
    """Where a scenario's fleet runs: the runner starts the routers with :meth:`start`, then
    the recorder and the agents through :attr:`fleet`, and faults the processes of ``fleet``.
    :class:`LocalHosting` is one router on this machine's loopback; the two hosts of
    services/hosts/fleet.py (``TwoHosts``) are another (routers on two network namespaces, a
    link between them that :meth:`partition` cuts)."""

    @property
    def fleet(self) -> Fleet: ...

    @property
    def endpoint(self) -> str:
        """Where the runner's session reaches the fleet."""
        ...

    def start_routers(self) -> None:
        """Start what the runner's session connects to; raises LaunchError."""

    def start_again(self, session: zenoh.Session, service: str, timeout: float) -> FaultEvent:
        """Start ``service`` again after a kill or stop and wait until it is back; raises
        FaultError (services/fault/process.py)."""
        ...

    def host(self, service: str) -> str | None:
        """The host ``service`` runs on (None: one host, not named)."""

    def partition(self, seconds: float | None) -> None:
        """Cut the link between the hosts (None: until :meth:`heal`); raises LaunchError
        where there is no link."""

    def heal(self) -> None: ...

    def stop(self) -> None: ...


@dataclass
class LocalHosting:
    """The fleet on this machine: one router on a free loopback port (``roco run``, ``roco
    scenario``, ``roco chaos``)."""

    run_dir: Path
    env: dict[str, str] = field(default_factory=dict)
    _fleet: Fleet | None = field(default=None, init=False, repr=False)

    @property
    def fleet(self) -> Fleet:
        if self._fleet is None:
            self._fleet = Fleet(self.run_dir, f"tcp/127.0.0.1:{free_port()}", env=self.env)
        return self._fleet

    @property
    def endpoint(self) -> str:
        return self.fleet.endpoint  # tls/… when the fleet runs on TLS (docs/security.md)

    def start_routers(self) -> None:
        self.fleet.start_router()

    def start_again(self, session: zenoh.Session, service: str, timeout: float) -> FaultEvent:
        from services.fault import process

        return process.start(self.fleet, service, timeout=timeout)

    def host(self, service: str) -> str | None:
        return None

    def partition(self, seconds: float | None) -> None:
        raise LaunchError("a fleet on one host has no link to cut (roco chaos --hosts has)")

    def heal(self) -> None:
        pass

    def stop(self) -> None:
        self.fleet.stop()


@dataclass
class CommandRecord:
    """One ``say`` step: its number (from 1), the sentence, a_hi's request id, every report
    a_hi gave about it, the final one, and what was expected; ``sent`` and ``ended``: when
    it was said and when its final report came (POSIX s; None: not yet)."""

    number: int
    text: str
    request_id: str
    expect: str | None = None
    expect_text: str | None = None
    reports: list[HumanReport] = field(default_factory=list)
    final: HumanReport | None = None
    sent: float | None = None
    ended: float | None = None

    def run_command(self) -> RunCommand:
        """What run.json keeps of it (services/runtime/run_folder.py)."""
        final = self.final
        return RunCommand(
            text=self.text,
            sent=self.sent,
            outcome=final.kind.value if final is not None else None,
            detail=final.text if final is not None else "",
            ended=self.ended,
        )

    @property
    def as_expected(self) -> bool:
        """Ended, in the expected kind (default: succeeded) and with the expected text."""
        if self.final is None:
            return False
        kind_ok = self.final.kind.value == (self.expect or "succeeded")
        text_ok = self.expect_text is None or self.expect_text.lower() in self.final.text.lower()
        return kind_ok and text_ok


@dataclass
class FaultRecord:
    """A fault the runner injected: when (s since the run started), what (a service's
    process, or ``link`` cut), the PIDs before and after (None for the link), how long the
    service took to be alive again (s; None: it was not), whether a command was still open
    when it hit, and the host it hit (None on one host)."""

    t: float
    service: str
    kind: str
    down_s: float
    pid_before: int | None
    pid_after: int | None = None
    back_after_s: float | None = None
    during_command: bool = False
    host: str | None = None


LINK = "link"
"""The service name of the link between two hosts in a ``fault`` (kind ``cut``)."""


@dataclass
class ScenarioOutcome:
    """How the scenario went: the commands, and ``detail`` when it stopped early; ``started``:
    POSIX time the fault times count from; ``interrupted``: ended by Ctrl-C (SIGINT), SIGTERM
    or SIGHUP (the fleet stopped all the same)."""

    commands: list[CommandRecord]
    detail: str = ""
    faults: list[FaultRecord] = field(default_factory=list)
    started: float = 0.0
    interrupted: bool = False
    raised: dict[str, dict[str, int]] = field(default_factory=dict)
    """Each agent's error counters above zero when the commands ended (services/runtime/raised.py)."""
    crashed: dict[str, list[int]] = field(default_factory=dict)
    """Each agent that exited though nobody stopped it (started again): its exit codes."""
    notices: list[tuple[float, HumanReport]] = field(default_factory=list)
    """What agents told the person unprompted (a_hi's ``notice`` reports): (s since the run
    started, the report), in the order a_hi told them."""

    @property
    def ok(self) -> bool:
        """Every command ended as expected and the run did not stop early (what the agents
        raised is :attr:`clean`)."""
        return not self.detail and all(c.as_expected for c in self.commands)

    @property
    def clean(self) -> bool:
        """No agent raised (its error counters all zero) and none exited by itself."""
        return not self.raised and not any(self.crashed.values())

    def raised_line(self) -> str:
        """What the agents raised, one line (services/runtime/raised.py); empty when clean."""
        return raised_text(self.raised, self.crashed)

    def summary(self) -> str:
        """One line per command, then one per notice to the person (the last
        :data:`SUMMARY_NOTICES`, after a line counting the earlier ones)."""
        lines = []
        for c in self.commands:
            got = f"{c.final.kind.value}: {c.final.text}" if c.final else "no outcome"
            mark = "ok" if c.as_expected else f"expected {c.expect or 'succeeded'}"
            lines.append(f"#{c.number} “{c.text}” → {got} [{mark}]")
        if len(self.notices) > SUMMARY_NOTICES:
            lines.append(
                f"({len(self.notices) - SUMMARY_NOTICES} earlier notices to the person: see the run's report)"
            )
        lines += [f"[{t:7.1f} s] {n.notice_line}" for t, n in self.notices[-SUMMARY_NOTICES:]]
        if self.detail:
            lines.append(self.detail)
        if not self.clean:
            lines.append(f"agents raised: {self.raised_line()}")
        return "\n".join(lines)


def system_of(env: dict[str, str]) -> SystemSpec:
    """The specification a fleet given the extra environment ``env`` runs (``ROCO_SPEC`` of
    ``env``, else of this process, else the shipped one: services/fleet/launcher.py
    ``Fleet.spec``)."""
    path = spec_path(env, os.environ)
    return default_spec() if path.resolve() == DEFAULT_SPEC.resolve() else load(path)


def _watched(key: str) -> bool:
    """Whether the runner reads communicates on ``key``: a_ta's to a_co (C1: its L_SW plan
    steps) and to a_km (C6: knowledge)."""
    return key.startswith(keys.fipa_key("C1", "a_ta", "a_co")) or key.startswith(
        keys.fipa_key("C6", "a_ta", "a_km")
    )


class ScenarioRunner:
    """Runs ``scenario`` in ``run_dir`` (created by the caller). ``env`` is the extra
    environment of every process (ag_ex's pacing and scene); ``echo`` receives progress
    lines (None: silent); ``on_session`` is given the runner's Zenoh session as soon as the
    router answers, before anything else starts (a live view subscribes on it); ``hosting``:
    where the fleet runs (default: :class:`LocalHosting`); ``gateway``: a port on 127.0.0.1
    where the fleet's ACL gateway serves agents of other FIPA platforms (``roco gateway``,
    docs/gateway.md), started once the agents are alive (None: no gateway, unless a ``say``
    step comes ``from = "gateway"``: then on a free port); ``ros2``: the arguments of the ROS 2
    face (``roco ros2 --all …``, docs/ros2.md), started once the agents are alive (None: none)."""

    def __init__(
        self,
        scenario: Scenario,
        run_dir: Path,
        *,
        env: dict[str, str] | None = None,
        echo: Echo | None = None,
        traffic_lines: Callable[[str, bytes], str | None] | None = None,
        info: RunInfo | None = None,
        on_session: Callable[[zenoh.Session], None] | None = None,
        hosting: Hosting | None = None,
        gateway: int | None = None,
        ros2: tuple[str, ...] | None = None,
    ) -> None:
        self.scenario = scenario
        self.ros2 = ros2
        from_platform = any(s.from_ == "gateway" for s in scenario.commands)
        self.gateway = gateway if gateway is not None or not from_platform else free_port()
        self.platform: ForeignPlatform | None = None
        """The foreign agent that says the ``from = "gateway"`` steps (made at the first)."""
        self.conversations: dict[str, CommandRecord] = {}
        """The foreign agent's commands, by its conversation-id."""
        self.on_session = on_session
        self.run_dir = run_dir
        self.hosting: Hosting = hosting if hosting is not None else LocalHosting(run_dir, env or {})
        self.system = system_of(env or {})
        """The specification the fleet runs (its agents, the person's, the start it waits for)."""
        self.echo = echo or (lambda line: None)
        self.traffic_lines = traffic_lines
        self.info = info or RunInfo()
        self.events: queue.SimpleQueue[tuple[str, object]] = queue.SimpleQueue()
        self.shown = ReportFilter()
        """a_hi's reports said: a command's, up to its final one (services/runtime/reports.py)."""
        self.steps_seen: list[str] = []  # a_ta's plan steps (C1 L_SW), in order
        self.knowledge = threading.Event()
        self.renewed = threading.Event()
        """a_ta renewed a_km's picture of a power-cycled robot's kitchen (WorldUpdate.renews)."""
        self.commands: list[CommandRecord] = []
        self.notices: list[tuple[float, HumanReport]] = []
        """a_hi's ``notice`` reports: what agents told the person (s since the run started)."""
        self.faults: list[FaultRecord] = []
        self.down: set[str] = set()  # services killed on purpose, not yet started again
        self.crashed: dict[str, list[int]] = {}
        """Each agent that exited though nobody stopped it: its exit codes, in order."""
        self.raised: dict[str, dict[str, int]] = {}
        """Each agent whose error counters were above zero when the commands ended
        (services/runtime/raised.py)."""
        self.last_act = time.monotonic()
        self.t0 = time.time()
        self.missed: MissedOutcomes | None = None
        """When to ask a_hi for outcomes the reports' subscriber missed (set once it follows them)."""
        self.session: zenoh.Session | None = None
        """The runner's session with the routers, once the fleet starts."""

    @property
    def fleet(self) -> Fleet:
        return self.hosting.fleet

    @property
    def endpoint(self) -> str:
        return self.hosting.endpoint

    @property
    def person(self) -> str:
        """The agent the person talks to: the one that plays the person's role (a_hi in the
        kitchen). Raises LaunchError when no agent of the specification plays it (the CLI
        refuses such a system before a runner is made)."""
        agent = self.system.playing("person")
        if agent is None:
            raise LaunchError(f'no agent of {self.system.system} plays the person\'s role (role = "person")')
        return agent

    # ---- events from Zenoh (callback threads: enqueue only) ----
    def _on_report(self, report: HumanReport) -> None:
        self.events.put(("report", report))

    def _on_traffic(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        for payload in unpack(sample.payload.to_bytes()):  # a batch: each communicate
            self._on_communicate(key, payload)

    def _on_line(self, key: str, payload: bytes) -> None:
        """The progress line of a communicate, when there are lines and it is worth one."""
        if self.traffic_lines is not None:
            line = self.traffic_lines(key, payload)
            if line is not None:
                self.events.put(("line", line))

    def _on_communicate(self, key: str, payload: bytes) -> None:
        self._on_line(key, payload)
        if not _watched(key):
            return
        try:
            msg = decode(payload)
            content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
        except (DecodeError, ContentError):
            return
        if isinstance(content, SWStatus) and content.step:
            self.events.put(("step", content.step))
        elif key.endswith("/a_km") and msg.performative is Performative.INFORM:
            self._km_learnt(content)

    def _km_learnt(self, content: object) -> None:
        """a_km was informed of the world (C6): it has knowledge; an update that renews it, a
        power-cycled robot's kitchen renewed."""
        self.knowledge.set()
        if isinstance(content, WorldUpdate) and content.renews:
            self.renewed.set()

    # ---- the run ----
    def _clock(self) -> str:
        return f"[{time.time() - self.t0:7.1f} s]"

    def _say(self, line: str) -> None:
        self.echo(f"{self._clock()} {line}")

    def _pump(self, timeout: float, deadline: float) -> None:
        """Take events for up to ``timeout`` s; raise LaunchError past ``deadline``. A process
        that exited though no fault stopped it is started again, the world's exit ends the run
        (:meth:`_start_crashed`). After a silence of the open commands' reports, a_hi
        is asked for their outcomes (services/runtime/reports.py ``MissedOutcomes``)."""
        if time.monotonic() > deadline:
            raise LaunchError(f"the scenario did not end within {self.scenario.timeout_s:.0f} s")
        dead = [n for n in self.fleet.dead() if n not in self.down]
        for name in dead:
            self._start_crashed(name)
        self._ask_missed()
        try:
            kind, item = self.events.get(timeout=timeout)
        except queue.Empty:
            return
        self._take(kind, item)

    def _take(self, kind: str, item: object) -> None:
        """One event: a progress line, a plan step of a_ta, a report of a_hi to the person, an
        answer the foreign agent received."""
        if kind == "line":
            self._say(str(item))
        elif kind == "step":
            self.steps_seen.append(str(item))
        elif kind == "report" and isinstance(item, HumanReport):
            self._report(item)
        elif kind == "foreign" and isinstance(item, Communicate):
            self._foreign_answer(item)

    def _ask_missed(self) -> None:
        """After a silence of the open commands' reports, their outcomes a_hi kept, as reports."""
        if self.missed is not None:
            for told in self.missed.ask_if_due([c.request_id for c in self.commands if c.final is None]):
                self._report(told)

    def _start_crashed(self, name: str) -> None:
        """Process ``name`` exited though nobody stopped it: an agent, the traffic recorder or a
        router is started again (as compose's restart policy does; a router on its endpoint,
        the sessions reconnect), its exit code kept in :attr:`crashed`, up to
        :data:`MAX_CRASHES` times; anything else (the world), or past that, ends the run
        (LaunchError)."""
        proc = self.fleet.processes[name]
        router = name.startswith("router")
        restartable = name in self.system.agent_names or name == "recorder" or router
        if not restartable or len(self.crashed.get(name, [])) >= MAX_CRASHES:
            raise LaunchError(f"process {name} exited during the run (see {self.run_dir}/logs)")
        self.crashed.setdefault(name, []).append(proc.returncode)
        if router:
            from services.fault.process import FaultError

            if self.session is None:  # before the fleet starts: the run's start fails
                raise LaunchError(f"process {name} exited before the fleet started (see {self.run_dir}/logs)")
            try:
                self.hosting.start_again(self.session, name, 60)
            except FaultError as exc:
                raise LaunchError(f"process {name} exited and did not start again: {exc}") from None
        else:
            self.fleet.restart(name)
        pid = self.fleet.processes[name].pid
        self.info.processes[name] = pid
        write_run_info(self.run_dir, self.info)
        self._say(f"{name} exited (code {proc.returncode}, see {log_of(name)}); started again (pid {pid})")

    def _report(self, item: HumanReport, to: str = "person") -> None:
        """a_hi's report to the person (or, ``to`` ``platform``, its answer to the foreign
        agent): said, and kept with its command (the final one ends it); a report of no command
        of the run, or after its command's final one, is ignored. A notice (an agent tells the
        person something unprompted) is said with its sender and kept in :attr:`notices`."""
        if item.kind is ReportKind.NOTICE:
            self.notices.append((round(time.time() - self.t0, 1), item))
            self._say(f"{self.person} → person: {item.notice_line}")
            return
        record = next((c for c in self.commands if c.request_id == item.request_id), None)
        if record is None or not self.shown.keep(item):
            return
        if self.missed is not None:
            self.missed.heard()
        record.reports.append(item)
        self._say(f"{self.person} → {to} (#{record.number}): {item.kind.value}: {item.text}")
        if item.kind in FINAL_REPORTS:
            record.final = item
            record.ended = time.time()

    def _ready(self, step: Step, steps_before: int) -> bool:
        t = step.after
        if t is None:
            return True
        if t.knowledge:
            return self.knowledge.is_set()
        if t.renewed:
            return self.renewed.is_set()
        if t.seconds is not None:
            return time.monotonic() - self.last_act >= t.seconds
        if t.ended is not None:
            return self.commands[t.ended - 1].final is not None
        assert t.step is not None
        return any(t.step in s for s in self.steps_seen[steps_before:])

    def _never(self, step: Step, steps_before: int, deadline: float) -> bool:
        """Whether ``step`` waits for a plan step that can no longer come: every command said so
        far has its final report (the events queued by then taken first)."""
        if step.after is None or step.after.step is None or not self.commands:
            return False
        if any(c.final is None for c in self.commands):
            return False
        self._pump(0.5, deadline)
        return not self._ready(step, steps_before)

    def _command(self, session: zenoh.Session, step: Step, text: str) -> None:
        """Say ``text``: a person's line on a_hi's human input, or a foreign agent's request
        through the gateway (``from = "gateway"``)."""
        record = CommandRecord(
            len(self.commands) + 1, text, uuid.uuid4().hex[:8], step.expect, step.expect_text
        )
        self.commands.append(record)
        record.sent = time.time()
        if step.from_ == "gateway":
            self._request_from_platform(record)
        else:
            payload = HumanInput(text=text, request_id=record.request_id, priority=step.priority)
            session.put(keys.HUMAN_IN, msgspec.json.encode(payload))
        if self.info.command_sent is None:
            self.info.command_sent = time.time()
            self.info.command = text
        self.info.commands.append(text)
        write_run_info(self.run_dir, self.info)
        speaker = "platform" if step.from_ == "gateway" else "person"
        self._say(f"{speaker} → {self.person} (#{record.number}): “{text}”")

    def _act(self, session: zenoh.Session, step: Step) -> None:
        if step.say is not None:
            self._command(session, step, step.say)
        elif step.disturb is not None:
            d = step.disturb
            disturbance = {"object": d.object, "delta": [d.dx, d.dy, d.dz], "tilt": d.tilt}
            session.put(keys.SIM_DISTURB, json.dumps(disturbance))
            turn = f", tipped {d.tilt:+.2f} rad" if d.tilt else ""
            self._say(f"the world: {d.object} moved by ({d.dx:+.3f}, {d.dy:+.3f}, {d.dz:+.3f}) m{turn}")
        elif step.fault is not None:
            self._fault(session, step.fault)
        elif step.restart is not None:
            pid = self.fleet.restart(step.restart)
            self.fleet.wait_alive(session, [step.restart], timeout=120)
            self.info.processes[step.restart] = pid
            write_run_info(self.run_dir, self.info)
            self._say(f"{step.restart} restarted (pid {pid})")

    def _request_from_platform(self, record: CommandRecord) -> None:
        """Post ``record``'s sentence to a_hi through the run's gateway as an agent of another
        FIPA platform (services/gateway/platform.py), its answers taken as events; LaunchError
        when its address cannot be bound or the gateway does not take the request."""
        assert self.gateway is not None  # a from = "gateway" step starts one (__init__)
        try:
            if self.platform is None:
                self.platform = ForeignPlatform(free_port(), lambda m: self.events.put(("foreign", m)))
                self.platform.start()
            url = f"http://127.0.0.1:{self.gateway}/acc"
            conversation = self.platform.request(url, "a_hi", record.text)
        except (MTPError, aiohttp.ClientError, OSError, TimeoutError) as exc:
            raise LaunchError(f"the foreign platform's request through the gateway: {exc}") from None
        self.conversations[conversation] = record

    def _foreign_answer(self, msg: Communicate) -> None:
        """An answer the foreign agent received, as a report of its command (its
        ``SentenceReport``: an ``agree`` accepted, an ``inform``, ``failure`` or ``refuse`` the
        final one); an answer that carries no report (e.g. the gateway's refusal with a reason)
        ends the command ``failed`` with the answer's text."""
        record = self.conversations.get(msg.conversation_id or "")
        if record is None:
            return
        try:  # a term crosses the gateway as JSON (services/gateway/bridge.py)
            content = (
                msgspec.json.decode(msg.content, type=SentenceReport) if msg.language == "L_HC" else None
            )
        except msgspec.DecodeError:
            content = None
        if content is not None and content.kind in KINDS:
            kind, text = ReportKind(content.kind), content.text
        else:
            kind = ReportKind.FAILED
            text = f"{msg.performative.value}: {msg.content.decode(errors='replace')[:300]}"
        self._report(HumanReport(request_id=record.request_id, kind=kind, text=text), to="platform")

    def _stop_platform(self) -> None:
        if self.platform is not None:
            self.platform.stop()

    def _wait_pumping(self, seconds: float) -> None:
        until = time.monotonic() + seconds
        while time.monotonic() < until:
            self._pump(min(0.1, max(0.0, until - time.monotonic())), math.inf)

    def _fault(self, session: zenoh.Session, fault: Fault) -> None:
        """Inject a process fault (services/scenario/model.py) with services/fault/process.py,
        or cut the link between two hosts (service ``link``), wait until the service is alive
        again (the run's events are taken meanwhile) and record it in the run folder's fault
        events (report section 8)."""
        from services.fault import process

        name = fault.service
        if name == LINK:
            self._cut(session, fault)
            return
        proc = self.fleet.processes.get(name)
        record = FaultRecord(
            round(time.time() - self.t0, 1),
            name,
            fault.kind,
            fault.down_s if fault.kind != "restart" else 0.0,
            proc.pid if proc is not None else None,
            during_command=any(c.final is None for c in self.commands),
            host=self.hosting.host(name),
        )
        self.faults.append(record)
        lasting = f" for {fault.down_s:.1f} s" if fault.kind != "restart" else ""
        where = f" on {record.host}" if record.host else ""
        self._say(f"fault: {fault.kind} {name}{where}{lasting}")
        t_fault = time.monotonic()
        events = []
        try:
            if fault.kind == "pause":
                events.append(process.pause(self.fleet, name))
                self._wait_pumping(fault.down_s)
                events.append(process.unpause(self.fleet, name))
            else:
                self.down.add(name)
                if fault.kind == "kill":
                    events.append(process.kill(self.fleet, name))
                    self._wait_pumping(fault.down_s)
                else:
                    events.append(process.stop(self.fleet, name, timeout=20))
                events.append(self.hosting.start_again(session, name, 120))
                self.down.discard(name)
        except process.FaultError as exc:
            raise LaunchError(f"fault on {name}: {exc}") from None
        record.pid_after = self.fleet.processes[name].pid
        self.info.processes[name] = record.pid_after
        write_run_info(self.run_dir, self.info)
        record.back_after_s = round(time.monotonic() - t_fault, 1)
        self._record_events(session, events)
        self._say(f"{name} is back after {record.back_after_s:.1f} s (pid {record.pid_after})")

    def _cut(self, session: zenoh.Session, fault: Fault) -> None:
        """Cut the link between the hosts for ``fault.down_s`` s (the hosting records it in
        the run folder's link.jsonl), as fault events ``partition``/``heal`` of ``link``."""
        from services.fault import process

        record = FaultRecord(
            round(time.time() - self.t0, 1),
            LINK,
            fault.kind,
            fault.down_s,
            None,
            during_command=any(c.final is None for c in self.commands),
            host="brain ↔ robot",
        )
        self.faults.append(record)
        self._say(f"fault: cut the link for {fault.down_s:.1f} s")
        t_fault = time.monotonic()
        events = [FaultEvent(t=time.time(), agent=process.INJECTOR, kind="partition", target=LINK)]
        self.hosting.partition(None)
        try:
            self._wait_pumping(fault.down_s)
        finally:
            self.hosting.heal()
        events.append(FaultEvent(t=time.time(), agent=process.INJECTOR, kind="heal", target=LINK))
        record.back_after_s = round(time.monotonic() - t_fault, 1)
        self._record_events(session, events)
        self._say(f"the link is up again after {record.back_after_s:.1f} s")

    def _record_events(self, session: zenoh.Session, events: list[FaultEvent]) -> None:
        """Have the traffic recorder write a fault's ``events`` (the run folder's faults.jsonl,
        report section 8); say so when it did not confirm them."""
        from services.fault import process

        if not process.record_events(session, events):
            kinds = ", ".join(f"{e.kind} {e.target}" for e in events)
            self._say(f"the traffic recorder did not confirm the fault events ({kinds}): not in the record")

    def _sync_recorder(self, session: zenoh.Session, timeout: float = 10.0) -> None:
        """Wait until the traffic recorder has written every communicate routed so far (the
        outcome a_hi reported included), so that stopping the fleet loses none of them
        (services/recorder/sync.py)."""
        if not sync(session, timeout):
            self._say(
                f"the traffic recorder did not confirm within {timeout:.0f} s; "
                "its record may lack the last communicates"
            )

    def run(self) -> ScenarioOutcome:
        """Run to the end; never raises for a failed run (the outcome says why)."""
        session: zenoh.Session | None = None
        detail = ""
        interrupted = False
        deadline = time.monotonic() + self.scenario.timeout_s
        try:
            session = self._open()
            self._start_fleet(session)
            self._await_knowledge(deadline)
            for step in self.scenario.steps:
                self._play(session, step, deadline)
            self._finish(session, deadline)
        except LaunchError as exc:
            detail = str(exc)
        except KeyboardInterrupt:
            detail, interrupted = "interrupted", True
        finally:
            if session is not None:
                session.close()
            self._stop_platform()
            if self._stop_hosting():
                detail, interrupted = "interrupted", True
            with contextlib.suppress(LaunchError):  # no fleet when the two hosts were never made
                self.info.processes = {**self.info.processes, **self.fleet.pids()}
        outcome = ScenarioOutcome(
            self.commands,
            detail,
            self.faults,
            self.t0,
            interrupted,
            self.raised,
            self.crashed,
            self.notices,
        )
        self._note_outcome(outcome)
        return outcome

    # ---- the phases of a run ----
    def _open(self) -> zenoh.Session:
        """Start the routers; the runner's session with them."""
        self.hosting.start_routers()
        self.info.router = self.endpoint
        self._say(f"run folder {self.run_dir}; router {self.endpoint}")
        return open_client(self.endpoint)

    def _start_fleet(self, session: zenoh.Session) -> None:
        """Hand ``session`` over, start the recorder, subscribe to the traffic and the reports,
        start the agents and note them once all are alive."""
        if self.on_session is not None:
            self.on_session(session)
        self.fleet.start_recorder()
        self.fleet.wait_alive(session, ["recorder"], timeout=60)
        session.declare_subscriber(keys.FIPA_ALL, self._on_traffic)
        follow_reports(session, self._on_report)  # also what a_hi said while the router was away
        self.missed = MissedOutcomes(session)  # and what it no longer has a cache of
        self.session = session
        self.fleet.start_agents()
        agents = self.system.launch_order
        waited = self.fleet.wait_alive(session, agents, timeout=120)
        self.info.processes = self.fleet.pids()
        write_run_info(self.run_dir, self.info)
        self._say(f"all agents alive after {waited:.1f} s: {', '.join(agents)}")
        if self.gateway is not None:
            self._start_gateway(session, self.gateway)
        if self.ros2 is not None:
            self.fleet.start_ros2(self.ros2)
            waited = self.fleet.wait_alive(session, [ROS2], timeout=60)
            self.info.processes = self.fleet.pids()
            write_run_info(self.run_dir, self.info)
            self._say(f"ROS 2 node /roco up after {waited:.1f} s: roco/say → a_hi (C9) and the robot's state")

    def _start_gateway(self, session: zenoh.Session, port: int) -> None:
        """Start the ACL gateway on ``port`` and wait until it serves (its liveliness token:
        LaunchError naming its last log line when it exits first, e.g. the port was taken)."""
        self.fleet.start_gateway(port)
        waited = self.fleet.wait_alive(session, [GATEWAY], timeout=60)
        self.info.processes = self.fleet.pids()
        write_run_info(self.run_dir, self.info)
        url = f"http://127.0.0.1:{port}/acc"
        self._say(f"gateway serving {url} after {waited:.1f} s: agents of other FIPA platforms → a_hi (C8)")

    def _await_knowledge(self, deadline: float) -> None:
        """Paper Table 7: a_km receives initial knowledge about the environment first (within
        60 s, else LaunchError). A system in which no a_ta informs an a_km (another than the
        kitchen) starts without."""
        if channel_between(self.system, "a_ta", "a_km") is None:
            return
        knowledge_by = time.monotonic() + 60
        while not self.knowledge.is_set():
            if time.monotonic() > knowledge_by:
                raise LaunchError("a_km received no initial knowledge from a_ta within 60 s")
            self._pump(0.1, deadline)
        self._say("a_km has initial knowledge of the scene")

    def _play(self, session: zenoh.Session, step: Step, deadline: float) -> None:
        """One step: once its trigger holds and its delay has passed, its action."""
        before = len(self.steps_seen)
        while not self._ready(step, before):
            self._pump(0.2, deadline)
            if step.after is not None and self._never(step, before, deadline):
                raise LaunchError(f"a step waits for {step.after.step!r}, but every command has ended")
        delay = step.after.delay_s if step.after is not None else 0.0
        if delay > 0:  # e.g. half-way through the step that triggered
            until = time.monotonic() + delay
            while (left := until - time.monotonic()) > 0:
                self._pump(min(0.05, left), deadline)
        self._act(session, step)
        self.last_act = time.monotonic()

    def _finish(self, session: zenoh.Session, deadline: float) -> None:
        """Once every command has its outcome: the agents' counters saved, the recorder synced
        and the remaining events taken."""
        while any(c.final is None for c in self.commands):
            self._pump(0.5, deadline)
        # what each agent says it put on Zenoh, then everything routed before is recorded
        self._save_counters(session)
        self._sync_recorder(session)
        # the lines of communicates that came after the final report (another subscriber's
        # thread) are still said: the person sees every step
        while not self.events.empty():
            self._pump(0.0, deadline)

    def _save_counters(self, session: zenoh.Session) -> None:
        """The agents' counters (and the gateway's: what crossed it, said in one line as
        ``roco status`` shows it) into the run folder's counters.json."""
        asked = [
            *self.system.launch_order,
            *([GATEWAY] if self.gateway is not None else []),
            *([ROS2] if self.ros2 is not None else []),
        ]
        counters = ask_counters(session, asked, timeout=10.0)
        save_counters(self.run_dir, counters)
        self.raised = raised_by_agent({a: r.counters for a, r in counters.items()})
        if self.raised:
            self._say(f"agents raised: {raised_text(self.raised, {})}")
        if GATEWAY in counters:
            from services.gateway.bridge import summary

            self._say(f"gateway: {summary(counters[GATEWAY].counters)}")
        if ROS2 in counters:
            from services.ros2.face import summary as ros2_summary

            self._say(f"ros2: {ros2_summary(counters[ROS2].counters)}")

    def _stop_hosting(self) -> bool:
        """Stop the fleet; whether a Ctrl-C came meanwhile (it starts the stop again: none is
        left)."""
        interrupted = False
        while True:
            try:
                self.hosting.stop()
                return interrupted
            except KeyboardInterrupt:
                interrupted = True

    def _note_outcome(self, outcome: ScenarioOutcome) -> None:
        """The run's end, its commands' outcomes and its verdict, into the run folder's info."""
        self.info.ended = time.time()
        self.info.outcomes = [c.run_command() for c in self.commands]
        self.info.succeeded = outcome.ok
        self.info.raised = outcome.raised
        self.info.crashed = {a: codes for a, codes in outcome.crashed.items() if codes}
        self.info.detail = outcome.detail or "; ".join(
            f"#{c.number} {c.final.kind.value}: {c.final.text}" for c in self.commands if c.final
        )
        write_run_info(self.run_dir, self.info)
