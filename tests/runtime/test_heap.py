"""An agent gives the memory its start-up freed back to the OS once it runs
(services/runtime/heap.py)."""

from __future__ import annotations

import json
import sys
import threading

import pytest

from services.runtime import engine as agent_module
from services.runtime.memory_transport import MemoryBus
from tests.runtime.test_agent_runtime import Counter
from tests.support.fresh import run_python

FREED_BELOW_A_LIVE_BLOCK = """
import json
from services.runtime.heap import give_back_freed_heap

def rss_mib():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024

blocks = [bytes(1024) for _ in range(100_000)]  # 100 MiB from glibc's heap (> pymalloc's 512 B)
pin = bytes(1024)  # above them: the heap's top cannot shrink by itself
del blocks
before = rss_mib()
trimmed = give_back_freed_heap()
print(json.dumps([trimmed, before, rss_mib()]))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_freed_heap_pages_are_given_back() -> None:
    done = run_python(FREED_BELOW_A_LIVE_BLOCK)
    assert done.returncode == 0, done.stderr[-2000:]
    trimmed, before, after = json.loads(done.stdout.strip().splitlines()[-1])
    assert trimmed is True
    assert before - after > 50, (before, after)  # most of the 100 MiB freed left the process


def test_an_agent_gives_back_once_its_first_step_has_blocked(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    called = threading.Event()
    agent = Counter(MemoryBus().transport())

    def record() -> bool:
        calls.append(agent.count)
        called.set()
        return True

    monkeypatch.setattr(agent_module, "give_back_freed_heap", record)
    agent.engine.bind()
    thread = threading.Thread(target=agent.engine.run, daemon=True)
    thread.start()
    assert called.wait(10)
    agent.engine.stop()
    thread.join(timeout=5)
    assert not thread.is_alive()
    assert calls == [5]  # once, after the 'count' behaviour's five steps, when 'answer' blocked
