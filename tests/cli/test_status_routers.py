"""``roco status`` names each router that answers with what access control refused the way an
operator knows it — its host (brain, robot) for the two hosts of ``roco hosts``, else its
endpoint — from the lines each router prints when it starts (services/runtime/router.py), kept
in the run folder's logs. (A fleet of ``roco up``: tests/cli/test_fleet_end.py.)"""

from __future__ import annotations

from pathlib import Path

from services.control.status import router_names

BRAIN, BRAIN_AGAIN, ROBOT, LOCAL = "a1b2c3d4e5f60718", "0f1e2d3c4b5a6978", "99887766554433221", "5e5e5e5e"


def _log(run_dir: Path, process: str, *lines: str) -> None:
    (run_dir / "logs").mkdir(parents=True, exist_ok=True)
    (run_dir / "logs" / f"{process}.stderr").write_text("".join(f"{line}\n" for line in lines))


def test_the_two_hosts_routers_are_named_by_their_host_across_restarts(tmp_path: Path) -> None:
    _log(
        tmp_path,
        "router_brain",
        f"roco router {BRAIN} listening on tls/127.0.0.1:7447, tls/10.1.0.1:7447; access control from S",
        "2026-01-01 zenoh log line that mentions roco router but is not its start",
        f"roco router {BRAIN_AGAIN} listening on tls/127.0.0.1:7447; access control from S",
    )
    _log(tmp_path, "router_robot", f"roco router {ROBOT} listening on tls/127.0.0.1:7447; access control")
    _log(tmp_path, "a_hi", f"roco router {LOCAL} listening on tcp/x:1")  # not a router's log
    assert router_names(tmp_path) == {BRAIN: "brain", BRAIN_AGAIN: "brain", ROBOT: "robot"}


def test_a_single_router_is_named_by_its_endpoint(tmp_path: Path) -> None:
    _log(tmp_path, "router", f"roco router {LOCAL} listening on tcp/127.0.0.1:7447; access control from S")
    assert router_names(tmp_path) == {LOCAL: "at tcp/127.0.0.1:7447"}


def test_without_a_run_folder_no_router_is_named(tmp_path: Path) -> None:
    assert router_names(None) == {}
    assert router_names(tmp_path / "gone") == {}
