"""``roco replay RUN --agent NAME``: one agent of a recorded run again, in process, fed what it
received in the run, its output compared with what it sent there.

A fresh instance of the agent runs on an in-memory bus (services/runtime/memory_transport.py)
on which every other agent is a stub: its liveliness token there when the agent saw it
(the run folder's presence record, by its time and cause: services/replay/presence.py), it puts
the communicates the record holds for the agent, in causal order (an answer after what it
answers: services/recorder/causal.py; an input once the replayed agent has sent what it had sent
before that input came: services/replay/driver.py), at the times they reached the agent (their
publishers' timestamps and paths: services/replay/record.py). The agent
reads its clock and draws its identifiers from :class:`~services.replay.sources.ReplaySources`
(the clock set from the record's times, seeded random bytes: services/runtime/sources.py), and
its elementary actions run on the caller's thread (``Engine.drive``), so a replay is
deterministic. What it sends is compared, communicate by
communicate, with what it sent in the run, up to identifiers and clock readings
(services/replay/compare.py). Modules: :mod:`~services.replay.record` (the agent's part of the
record), :mod:`~services.replay.sources`, :mod:`~services.replay.compare`,
:mod:`~services.replay.driver` (the replay itself).
"""
