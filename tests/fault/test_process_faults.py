"""Process faults on a local fleet through `roco fault` (the state file of `roco up`):
pause/unpause, kill/start, restart, stop; PIDs updated; the faults recorded."""

from __future__ import annotations

import msgspec

from services.fault.process import FLEET_FILE, proc_state
from services.runtime.faults import FaultEvent
from shared.fipa_codec import Performative
from tests.fault.conftest import LiveFleet


def pids(live: LiveFleet) -> dict[str, int]:
    return dict(msgspec.json.decode((live.runs_dir / FLEET_FILE).read_bytes())["pids"])


def test_pause_unpause_kill_start_restart_stop(live: LiveFleet) -> None:
    km = pids(live)["a_km"]

    out = live.roco("pause", "a_km")
    assert out.returncode == 0, out.stderr
    assert proc_state(km) == "T"
    live.query("q-paused")  # waits in a_km's socket buffer
    out = live.roco("unpause", "a_km")
    assert out.returncode == 0, out.stderr
    assert proc_state(km) != "T"
    assert live.answer("q-paused")[-1].performative is Performative.INFORM_REF

    out = live.roco("kill", "a_km")
    assert out.returncode == 0, out.stderr
    assert f"killed a_km (pid {km})" in out.stdout
    assert live.fleet.processes["a_km"].wait(timeout=10) == -9
    live.wait_alive("a_km", alive=False)
    out = live.roco("pause", "a_km")
    assert out.returncode == 1 and out.stderr.strip() == "roco: a_km is not running"

    out = live.roco("start", "a_km")
    assert out.returncode == 0, out.stderr
    km2 = pids(live)["a_km"]
    assert km2 != km and f"started a_km (pid {km2})" in out.stdout
    live.wait_alive("a_km")  # start waited for its token already
    live.query("q-started")
    assert live.answer("q-started")[-1].performative is Performative.INFORM_REF
    out = live.roco("start", "a_km")
    assert out.returncode == 1 and "running already" in out.stderr

    out = live.roco("restart", "a_km")
    assert out.returncode == 0, out.stderr
    km3 = pids(live)["a_km"]
    assert km3 not in (km, km2) and proc_state(km2) in (None, "Z")

    out = live.roco("stop", "a_km")
    assert out.returncode == 0, out.stderr
    assert "SIGTERM" in out.stdout and proc_state(km3) in (None, "Z")

    def recorded(events: list[FaultEvent]) -> bool:
        kinds = [(e.agent, e.kind, e.target) for e in events]
        want = ["pause", "unpause", "kill", "start", "restart", "stop"]
        return [k for a, k, t in kinds if a == "roco" and t == "a_km"] == want

    live.recorded_faults(recorded)
