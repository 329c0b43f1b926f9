"""shared.fipa_codec.message.new_id: identifiers drawn from ``os.urandom`` in reads of many,
each handed out once, in any thread and in a forked child."""

from __future__ import annotations

import os
import threading

from shared.fipa_codec.message import _IDS_PER_READ, new_id


def test_identifiers_are_twelve_hex_digits_after_the_prefix_and_never_repeat() -> None:
    ids = [new_id("c-") for _ in range(3 * _IDS_PER_READ + 7)]  # across several reads
    assert all(i.startswith("c-") and len(i) == 14 and int(i[2:], 16) >= 0 for i in ids)
    assert len(set(ids)) == len(ids)


def test_threads_drawing_at_once_get_distinct_identifiers() -> None:
    drawn: list[list[str]] = [[] for _ in range(4)]

    def draw(out: list[str]) -> None:
        out.extend(new_id() for _ in range(2 * _IDS_PER_READ))

    threads = [threading.Thread(target=draw, args=(out,)) for out in drawn]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    every = [i for out in drawn for i in out]
    assert len(set(every)) == len(every) == 8 * _IDS_PER_READ


def test_a_forked_child_does_not_reuse_the_identifiers_its_parent_drew_ahead() -> None:
    new_id()  # the parent has identifiers drawn ahead
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: its next identifier, to the parent
        os.close(read)
        os.write(write, new_id().encode())
        os._exit(0)
    os.close(write)
    child = os.read(read, 64).decode()
    os.close(read)
    os.waitpid(pid, 0)
    assert child != new_id()
