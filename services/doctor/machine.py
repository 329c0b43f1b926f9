"""What the machine allows: off-screen rendering (EGL or OSMesa) for the head camera,
SCHED_FIFO, CPU pinning and the CPU latency request for the 1 kHz loop, loopback ports for
the router.

The rendering and scheduling probes run in a child Python process (a failed GL context can
abort a process; a real-time policy must not stay on this one), each with a time limit."""

from __future__ import annotations

import os
import socket
import subprocess
import sys

from services.doctor.model import Check, Use
from shared.settings import ROUTER_PORT
from velma.gl import HOW as EGL_HOW

PROBE_TIMEOUT_S = 60.0

GL_MODEL = (
    '<mujoco><worldbody><light pos="0 0 2"/>'
    '<geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></worldbody></mujoco>'
)
"""The probe's scene: a lit red box in front of MuJoCo's free camera (about a quarter of the
frame red, the rest background)."""
GL_PROBE = (
    "import sys, mujoco\n"
    "m = mujoco.MjModel.from_xml_string(sys.argv[1])\n"
    "d = mujoco.MjData(m)\n"
    "mujoco.mj_forward(m, d)\n"
    "with mujoco.Renderer(m, 64, 64) as r:\n"
    "    r.update_scene(d)\n"
    "    image = r.render()\n"
    "if image.min() == image.max():\n"
    "    sys.exit(f'the rendered image is constant (every value {image.min()})')\n"
)
"""Renders the model XML given as its argument at 64 × 64 off-screen (``mujoco.Renderer``, as
velma/render.py does); exits non-zero when no context opens or the image is one colour."""
FIFO_PROBE = "import os\nos.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))\n"
PIN_PROBE = "import os, sys\nos.sched_setaffinity(0, {int(sys.argv[1])})\n"

GL_HOW = {
    "egl": f"{EGL_HOW} (software EGL is enough)",
    "osmesa": "apt-get install libosmesa6, then run with MUJOCO_GL=osmesa",
}


def probe(code: str, *args: str, env: dict[str, str] | None = None) -> tuple[bool, str]:
    """Run ``code`` in a child interpreter; (exited 0, last line of its stderr). A child that
    does not end within ``PROBE_TIMEOUT_S`` counts as failed."""
    try:
        done = subprocess.run(
            [sys.executable, "-c", code, *args],
            env={**os.environ, **(env or {})},
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT_S,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return False, f"no answer within {PROBE_TIMEOUT_S:.0f} s"
    except OSError as exc:
        return False, str(exc)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return done.returncode == 0, (lines[-1] if lines else f"exit status {done.returncode}")


def rendering_checks(env: dict[str, str] | None = None, model: str = GL_MODEL) -> list[Check]:
    """Whether MuJoCo renders ``model`` (XML) off-screen with EGL (what velma/render.py and the
    head camera use) and, where EGL fails, OSMesa: one check per backend tried, each in a child
    interpreter with ``env`` added to this one's environment. A backend counts only when the
    image it renders is not constant (a context that opens but draws nothing fails)."""
    out = []
    for backend in ("egl", "osmesa"):
        ok, why = probe(GL_PROBE, model, env={**(env or {}), "MUJOCO_GL": backend})
        name = backend.upper() if backend == "egl" else "OSMesa"
        detail = "MuJoCo renders off-screen" if ok else f"does not render: {why}"
        out.append(Check(name, Use.CAMERA, ok, detail, "" if ok else GL_HOW[backend]))
        if ok:
            break
    return out


def cannot_render(env: dict[str, str] | None = None, model: str = GL_MODEL) -> str | None:
    """Why MuJoCo renders off-screen with neither EGL nor OSMesa here (each backend's reason,
    and the packages that give software EGL), in one line; None when one renders
    (:func:`rendering_checks`)."""
    checks = rendering_checks(env, model)
    if any(c.found for c in checks):
        return None
    why = "; ".join(f"{c.name} {c.detail}" for c in checks)
    return f"MuJoCo cannot render off-screen ({why}): {checks[0].how}"


def fifo_check() -> Check:
    """Whether a process may take SCHED_FIFO (velma/realtime.py ``enter_realtime``)."""
    if not hasattr(os, "sched_setscheduler"):
        return Check("SCHED_FIFO", Use.REALTIME, False, "not available on this OS", "Linux")
    ok, why = probe(FIFO_PROBE)
    return Check(
        "SCHED_FIFO",
        Use.REALTIME,
        ok,
        "allowed" if ok else f"refused: {why}",
        ""
        if ok
        else "run as root, or raise the rtprio limit (limits.conf: '<user> - rtprio 90'); "
        "containers: --ulimit rtprio=90, or as root --cap-add SYS_NICE",
    )


def pinning_check() -> Check:
    """Whether the loop can have a CPU of its own: two CPUs or more, and affinity allowed."""
    if not hasattr(os, "sched_getaffinity"):
        return Check("CPU pinning", Use.REALTIME, False, "not available on this OS", "Linux")
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        return Check(
            "CPU pinning", Use.REALTIME, False, f"{len(cpus)} CPU available", "a machine with 2 CPUs or more"
        )
    ok, why = probe(PIN_PROBE, str(cpus[-1]))
    return Check(
        "CPU pinning",
        Use.REALTIME,
        ok,
        f"allowed ({len(cpus)} CPUs; the loop takes CPU {cpus[-1]})" if ok else f"refused: {why}",
        "" if ok else "allow sched_setaffinity (containers: --cpuset-cpus, no seccomp block)",
    )


def cpu_latency_check(device: str | None = None) -> Check:
    """Whether the loop may hold the CPUs' wake-up latency at 0 µs (PM QoS; velma/executor/
    realtime.py ``hold_cpu_latency``): ``device`` (default the loop's ``PM_QOS_DEVICE``) exists
    and this user may write it. Not needed, but without it the loop's cycles come back to
    cold caches after each sleep. The loop's module is imported here, not with this one, so
    that a broken install still gets the doctor's other checks."""
    if device is None:
        try:
            from velma.realtime import PM_QOS_DEVICE
        except ImportError as exc:
            why = f"cannot tell: {exc}"
            return Check("CPU latency request", Use.REALTIME, False, why, "pip install -e .")
        device = PM_QOS_DEVICE
    if not os.path.exists(device):
        return Check("CPU latency request", Use.REALTIME, False, f"no {device}", "Linux with PM QoS")
    ok = os.access(device, os.W_OK)
    return Check(
        "CPU latency request",
        Use.REALTIME,
        ok,
        f"{device} writable: idle CPUs will poll while the loop runs" if ok else f"{device} not writable",
        "" if ok else f"run as root, or grant write access to {device} (containers: --device {device})",
    )


def port_free(port: int, host: str = "127.0.0.1") -> bool:
    """Whether TCP ``port`` on ``host`` can be bound now (0: any port)."""
    with socket.socket() as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def port_checks(router_port: int = ROUTER_PORT) -> list[Check]:
    """A free loopback port (``roco run`` starts its router on one) and ``router_port``
    (``roco up``'s default)."""
    any_free = port_free(0)
    fixed = port_free(router_port)
    return [
        Check(
            "loopback port",
            Use.RUN,
            any_free,
            "a free TCP port on 127.0.0.1 can be bound"
            if any_free
            else "no TCP port on 127.0.0.1 can be bound",
            "" if any_free else "bring up the loopback interface (ip link set lo up)",
        ),
        Check(
            f"port {router_port}",
            Use.UP,
            fixed,
            f"127.0.0.1:{router_port} is free" if fixed else f"127.0.0.1:{router_port} is taken",
            "" if fixed else f"roco up --port <another>, or stop what listens on {router_port}",
        ),
    ]


def checks() -> list[Check]:
    return [*port_checks(), *rendering_checks(), fifo_check(), pinning_check(), cpu_latency_check()]
