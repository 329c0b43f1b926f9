"""Process and network faults on a Docker Compose deployment (``deploy/compose.yaml``).

- process faults: ``docker compose -f FILE [-p PROJECT] kill|stop|start|pause|unpause|restart
  SERVICE`` (``docker-compose`` when the ``docker compose`` plugin is absent);
- partition: ``docker network disconnect`` the service's container from each of its
  networks (remembered, with the container's aliases, in ``runs/.fault_partitions.json``) and
  ``docker network connect --alias …`` to heal; without a record, the project's default
  network ``<project>_default`` with the service name as alias;
- delay and loss: ``docker exec -u 0 CONTAINER tc qdisc replace dev eth0 root netem delay …ms
  loss …%`` (``tc qdisc del dev eth0 root`` to clear), as root in the container: the services
  run as the image's user, and a capability the container is granted is a root process's
  only (capabilities(7): a non-root exec gets none). This needs three things, and a failure
  names the one missing (:func:`netem_failure`): ``tc`` (Debian's ``iproute2``) in the
  service's image, the ``NET_ADMIN`` capability (the override deploy/compose.netfault.yaml
  grants it) and the host kernel's netem queueing discipline (``sch_netem``).

The compose command is ``docker compose`` or ``docker-compose`` (services/deploy/engine.py);
the command runner is injectable (tests check the command lines without a Docker engine).
"""

from __future__ import annotations

import contextlib
import json
import shutil
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from services.deploy.compose import agent_extras, hardware
from services.deploy.engine import compose_command, last_line, run_command
from services.fault.process import INJECTOR, FaultError
from services.runtime.faults import FaultEvent
from services.spec.model import SystemSpec, default_spec


def compose_services(system: SystemSpec) -> tuple[str, ...]:
    """The services of a compose deployment of ``system`` a fault can reach: the router, the
    hardware the agents drive (the world), one per agent (services/deploy/compose.py renders
    them), the recorder and the viewer."""
    return ("router", *hardware(system), *system.launch_order, "recorder", "viewer")


def joined_services(system: SystemSpec) -> dict[str, tuple[str, ...]]:
    """Per hardware service of ``system``, the agents that share its IPC and PID namespaces
    (ag_ex the world's): they end with it, and Docker does not start them again when it tries
    before the hardware is back ("can't join IPC of container …"), so a fault that starts the
    hardware starts them after it."""
    return {
        h: tuple(n for n in system.launch_order if agent_extras(system, n).hardware == h)
        for h in hardware(system)
    }


COMPOSE_SERVICES = compose_services(default_spec())
"""The services of the shipped deploy/compose.yaml (the Robot Companion's)."""
DEFAULT_FILE = Path("deploy/compose.yaml")
PARTITIONS_FILE = ".fault_partitions.json"

NETFAULT_FILE = Path("deploy/compose.netfault.yaml")
"""The override that grants NET_ADMIN to the services network faults reach
(services/deploy/netfault.py writes it)."""

TC_EXEC = ("docker", "exec", "-u", "0")
"""How ``tc`` runs in a service's container: as root there, where the NET_ADMIN capability of
deploy/compose.netfault.yaml counts (the service itself runs as the image's user)."""

Runner = Callable[[Sequence[str]], "subprocess.CompletedProcess[str]"]


def netem_failure(service: str, out: subprocess.CompletedProcess[str]) -> str:
    """Why ``tc … netem`` in ``service``'s container failed (``out``: what ``docker exec``
    gave), naming the missing piece: ``tc`` in the image (the exec cannot start it), the
    ``NET_ADMIN`` capability (``Operation not permitted``) or the kernel's netem (``Specified
    qdisc kind is unknown``, or ``No such file or directory`` from the kernel on an older
    iproute2); else tc's own last line."""
    text = f"{out.stderr}\n{out.stdout}"
    said = last_line(out.stderr) or last_line(out.stdout) or f"exit code {out.returncode}"
    if "executable file not found" in text or "tc: not found" in text or out.returncode == 127:
        return f"{service}'s image has no tc (Debian's iproute2; deploy/Dockerfile installs it): {said}"
    if "Operation not permitted" in text:
        return (
            f"{service}'s container lacks the NET_ADMIN capability: start the fleet with "
            f"-f {NETFAULT_FILE} as well (docs/faults.md): {said}"
        )
    if "qdisc kind is unknown" in text or ("RTNETLINK" in text and "No such file or directory" in text):
        return f"the host's kernel has no netem (modprobe sch_netem on the host, or a kernel with it): {said}"
    return f"tc in {service} failed: {said}"


@dataclass
class Compose:
    """One compose deployment: its ``file``, ``project`` name (None: compose's default, the
    file's folder name), where partitions are remembered (``state_dir``), the ``services`` a
    fault may reach (:func:`compose_services` of the specification it runs)."""

    file: Path = DEFAULT_FILE
    project: str | None = None
    state_dir: Path = Path("runs")
    run: Runner = run_command
    services: tuple[str, ...] = COMPOSE_SERVICES
    joined: dict[str, tuple[str, ...]] = field(default_factory=lambda: joined_services(default_spec()))
    """:func:`joined_services` of the deployment's specification."""
    _base: list[str] | None = field(default=None, init=False, repr=False)

    # ---- docker ---------------------------------------------------------------------------
    def base(self) -> list[str]:
        """``docker compose -f FILE [-p PROJECT]`` or ``docker-compose …``; FaultError when
        neither is installed."""
        if self._base is None:
            cmd = compose_command(self.run, shutil.which)
            if cmd is None:
                raise FaultError("neither 'docker compose' nor 'docker-compose' is installed")
            cmd += ["-f", str(self.file)]
            if self.project:
                cmd += ["-p", self.project]
            self._base = cmd
        return self._base

    def _check(self, args: Sequence[str], what: str) -> str:
        out = self.run(args)
        if out.returncode != 0:
            why = last_line(out.stderr) or last_line(out.stdout) or f"exit code {out.returncode}"
            raise FaultError(f"{what} failed: {why}")
        return out.stdout

    @property
    def project_name(self) -> str:
        return self.project or self.file.resolve().parent.name

    def container(self, service: str) -> str:
        """The id of ``service``'s container; FaultError when it has none."""
        self._check_service(service)
        out = self._check([*self.base(), "ps", "-q", service], f"docker compose ps {service}")
        ids = out.split()
        if not ids:
            raise FaultError(f"{service} has no container in compose project {self.project_name}")
        return ids[0]

    # ---- process faults -------------------------------------------------------------------
    def process(self, action: str, service: str) -> FaultEvent:
        """``docker compose ACTION SERVICE``; after a start or restart of a hardware service,
        ``docker compose start`` of the agents that share its namespaces (:attr:`joined`).
        Raises FaultError for an unknown service or action, or a docker command that fails."""
        self._check_service(service)
        if action not in ("kill", "stop", "start", "pause", "unpause", "restart"):
            raise FaultError(f"unknown process fault {action!r}")
        self._check([*self.base(), action, service], f"docker compose {action} {service}")
        again = self.joined.get(service, ()) if action in ("start", "restart") else ()
        if again:  # they ended with it (one PID namespace): started once it is back
            # start, not up: up would make them anew in this command's environment
            self._check([*self.base(), "start", *again], f"docker compose start {' '.join(again)}")
            said = f"; {', '.join(again)} started again after it (they share its namespaces)"
            return _event(action, service, f"compose project {self.project_name}{said}")
        return _event(action, service, f"compose project {self.project_name}")

    # ---- network faults -------------------------------------------------------------------
    def netem(self, service: str, delay_s: float, loss: float, dev: str = "eth0") -> FaultEvent:
        """Egress delay and loss of ``service``'s container with tc netem (both 0: cleared);
        FaultError naming what is missing when tc fails (:func:`netem_failure`)."""
        cid = self.container(service)
        if not delay_s and not loss:
            out = self.run([*TC_EXEC, cid, "tc", "qdisc", "del", "dev", dev, "root"])
            if (
                out.returncode != 0
                and "No such file" not in out.stderr
                and "handle of zero" not in out.stderr
            ):
                raise FaultError(netem_failure(service, out))
            return _event("net", service, "netem cleared")
        netem = ["netem"]
        if delay_s:
            netem += ["delay", f"{delay_s * 1000:g}ms"]
        if loss:
            netem += ["loss", f"{loss * 100:g}%"]
        out = self.run([*TC_EXEC, cid, "tc", "qdisc", "replace", "dev", dev, "root", *netem])
        if out.returncode != 0:
            raise FaultError(netem_failure(service, out))
        return _event("net", service, " ".join(netem))

    def _partitions(self) -> dict[str, dict[str, list[str]]]:
        try:
            data = json.loads((self.state_dir / PARTITIONS_FILE).read_text())
        except (OSError, ValueError):
            return {}
        return data if isinstance(data, dict) else {}

    def _save_partitions(self, data: dict[str, dict[str, list[str]]]) -> None:
        self.state_dir.mkdir(parents=True, exist_ok=True)
        path = self.state_dir / PARTITIONS_FILE
        if data:
            path.write_text(json.dumps(data, indent=1))
        elif path.exists():
            path.unlink()

    def partition(self, service: str) -> FaultEvent:
        """Disconnect ``service``'s container from all its networks."""
        cid = self.container(service)
        out = self._check(
            ["docker", "inspect", "-f", "{{json .NetworkSettings.Networks}}", cid],
            f"docker inspect {service}",
        )
        try:
            networks = json.loads(out) or {}
        except ValueError:
            raise FaultError(f"docker inspect {service}: unexpected output") from None
        if not networks:
            raise FaultError(f"{service} is on no network (partitioned already?)")
        saved = self._partitions()
        record: dict[str, list[str]] = {}
        for net, conf in networks.items():
            aliases = [a for a in (conf or {}).get("Aliases") or [] if not cid.startswith(a)]
            record[net] = sorted(set(aliases) | {service})
            self._check(["docker", "network", "disconnect", net, cid], f"docker network disconnect {service}")
        saved[service] = record
        self._save_partitions(saved)
        return _event("partition", service, "disconnected from " + ", ".join(sorted(record)))

    def heal(self, service: str) -> FaultEvent:
        """Connect ``service``'s container again to the networks it was disconnected from."""
        cid = self.container(service)
        saved = self._partitions()
        record = saved.pop(service, None) or {f"{self.project_name}_default": [service]}
        for net, aliases in record.items():
            args = ["docker", "network", "connect"]
            for alias in aliases:
                args += ["--alias", alias]
            self._check([*args, net, cid], f"docker network connect {service}")
        self._save_partitions(saved)
        return _event("heal", service, "connected to " + ", ".join(sorted(record)))

    def partitioned(self) -> list[str]:
        return sorted(self._partitions())

    # ---- what `roco fault net` and `clear` apply -----------------------------------------
    def net(
        self, service: str, delay: float | None, loss: float | None, partition: bool | None, dev: str
    ) -> list[FaultEvent]:
        """`roco fault net` on ``service``'s container: netem when the ``delay`` (s) or the
        ``loss`` is given, then a ``partition`` (True) or its healing (False); the events
        applied. Raises FaultError at the first that cannot be."""
        events = []
        if delay is not None or loss is not None:
            events.append(self.netem(service, delay or 0.0, loss or 0.0, dev))
        if partition is True:
            events.append(self.partition(service))
        elif partition is False:
            events.append(self.heal(service))
        return events

    def clear(self, target: str | None, dev: str) -> list[FaultEvent]:
        """`roco fault clear` on the containers of ``target`` (None: every service): a
        partition healed, netem removed (every service: where it can be); the events applied.
        Raises FaultError at the first that cannot be."""
        events = []
        for service in [target] if target else self.services:
            if service in self.partitioned():
                events.append(self.heal(service))
            if target is not None:
                events.append(self.netem(service, 0.0, 0.0, dev))
            else:
                # not running, or no tc in its image: nothing to clear there
                with contextlib.suppress(FaultError):
                    events.append(self.netem(service, 0.0, 0.0, dev))
        return events

    def tc_show(self, service: str, dev: str = "eth0") -> str:
        cid = self.container(service)
        out = self.run([*TC_EXEC, cid, "tc", "qdisc", "show", "dev", dev])
        return out.stdout.strip() if out.returncode == 0 else f"(tc: {last_line(out.stderr)})"

    def _check_service(self, service: str) -> None:
        if service not in self.services:
            raise FaultError(f"no service {service!r} (services: {', '.join(self.services)})")


def _event(kind: str, service: str, detail: str) -> FaultEvent:
    return FaultEvent(t=time.time(), agent=INJECTOR, kind=kind, target=service, detail=detail)
