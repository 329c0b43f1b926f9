"""An agent's process imports only what the agent uses (lean processes): no physics
(MuJoCo, Pinocchio), plotting (matplotlib), visualisation (Rerun) or RDF (rdflib, pyoxigraph)
library in an agent that does not need it.

Each check runs in a fresh interpreter (``subprocess``: a new process, nothing inherited from
this test process, which has imported everything) that does what ``services.runtime.main``
does before the agent runs: load the specification, import the agent's class, build the agent
(here on an in-memory transport), and prints ``sys.modules``' heavy libraries.

ag_ex's processes each load only the physics they compute with, read from the shared libraries
a running process maps (``/proc/PID/maps``): the world process MuJoCo, without Pinocchio; the
loop Pinocchio and MuJoCo (its mirror of the kitchen); neither loads a GL platform (velma/gl.py
``never_renders``: the head camera renders in a process of its own).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.support.fresh import ROOT, run_python
from tests.support.machine import needs_gl
from velma.world.files import LINK_FILE, link_name

HEAVY = ("mujoco", "pinocchio", "matplotlib", "rerun", "rdflib", "pyoxigraph")
"""Libraries no lean agent may load."""
OPENSSL = "_hashlib"
"""hashlib's OpenSSL binding: ≈ 3.3 MiB resident (libcrypto), loaded by ``import hashlib``; the
runtime takes its digests from CPython's own modules (dedup.py, native.py). Not checked in the
synthetic probe: multiprocessing's pipes (the benchmark's) import hmac, hence hashlib."""
NEEDS = {"a_km": {"rdflib", "pyoxigraph", OPENSSL}, "a_hi": {OPENSSL}}
"""What an agent of the Robot Companion may load because it uses it (a_km's world model is RDF,
which also loads OpenSSL; a_hi's grammar parser, lark, hashes its grammar with hashlib)."""

PROBE = """
import json, sys
import services.runtime.main as main
from services.runtime.memory_transport import MemoryBus
from services.spec.model import default_spec
spec = default_spec()
cls = main.agent_class(spec, {name!r})
if {build!r}:
    cls(MemoryBus().transport(), spec)
print(json.dumps([n for n in {heavy!r} if n in sys.modules]))
"""

SYNTHETIC_PROBE = """
import json, sys
from multiprocessing import Pipe
from services.bench.synthetic import BenchInitiator, BenchParticipant, bench_spec
from services.runtime.memory_transport import MemoryBus
spec = bench_spec(1)
bus = MemoryBus()
BenchInitiator(bus.transport(), spec, Pipe()[0])
BenchParticipant(bus.transport(), spec, Pipe()[0])
print(json.dumps([n for n in {heavy!r} if n in sys.modules]))
"""


def loaded(code: str) -> set[str]:
    """The heavy libraries a fresh interpreter running ``code`` has imported (its last line)."""
    done = run_python(code)
    assert done.returncode == 0, done.stderr[-2000:]
    return set(json.loads(done.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize("name", ["a_hi", "a_co", "a_pl", "a_km", "a_ta"])
def test_a_built_agent_loads_only_the_heavy_libraries_it_uses(name: str) -> None:
    got = loaded(PROBE.format(name=name, build=True, heavy=(*HEAVY, OPENSSL)))
    assert got <= NEEDS.get(name, set()), (name, got - NEEDS.get(name, set()))


STDLIB_UNUSED = ("tempfile", "shutil", "lzma", "bz2", "importlib.resources")
"""Standard modules the runtime does not use (≈ 0.8 MiB resident together): ``importlib.abc``
imports them all through ``importlib.resources``; services/runtime/native.py's finder does
without it."""


@pytest.mark.parametrize("name", ["a_co", "a_ta"])
def test_the_runtime_loads_no_temporary_file_or_archive_module(name: str) -> None:
    """a_co and a_ta use nothing beyond the runtime and the codec: what they load, every agent
    pays for (a_hi's parser, a_pl's planner and a_km's RDF store load some of these modules
    themselves)."""
    assert loaded(PROBE.format(name=name, build=True, heavy=STDLIB_UNUSED)) == set()


def test_the_executor_agent_loads_no_physics_when_built(tmp_path: Path) -> None:
    """ag_ex's communication side, built as a fleet builds it (its world process has named its
    link in the run folder: velma/world/files.py), imports no physics and no GL: MuJoCo and
    Pinocchio are its loop's and its world's, the renderer its camera process's."""
    (tmp_path / LINK_FILE).write_text("roco-world-test\n")
    code = f"import os\nos.environ['ROCO_RUN_DIR'] = {str(tmp_path)!r}\n" + PROBE.format(
        name="ag_ex", build=True, heavy=(*HEAVY, "OpenGL")
    )
    assert loaded(code) == set()


def test_a_synthetic_agent_loads_no_heavy_library() -> None:
    """The benchmark's synthetic agents (services/bench/synthetic.py) are the runtime alone."""
    assert loaded(SYNTHETIC_PROBE.format(heavy=HEAVY)) == set()


def test_the_probe_sees_a_heavy_library_when_one_is_imported() -> None:
    """The check can fail: an agent module that imported rdflib would be caught."""
    assert "rdflib" in loaded(f"import rdflib\n{SYNTHETIC_PROBE.format(heavy=HEAVY)}")


def test_a_session_with_credentials_does_not_load_the_certificate_library(tmp_path: Path) -> None:
    """Every process of a fleet with access control reads its identity from the credentials
    folder (services/security/folder.py); only issuing them needs ``cryptography``."""
    from services.security.certs import issue, issue_router, make_ca

    make_ca(tmp_path)
    issue_router(tmp_path)
    issue(tmp_path, ["a_co"])
    code = (
        "import json, sys\n"
        "from pathlib import Path\n"
        "from services.runtime.zenoh_config import client_config\n"
        f"client_config(['tls/127.0.0.1:7447'], identity='a_co', security=Path({str(tmp_path)!r}))\n"
        "print(json.dumps([n for n in ('cryptography', 'rdflib') if n in sys.modules]))\n"
    )
    assert loaded(code) == set()


@needs_gl
def test_the_executor_observes_with_the_camera_without_loading_the_renderer() -> None:
    """ag_ex's communication side runs the loop and the camera in child processes
    (velma/executor/process.py, velma/executor/camera_process.py): after a camera Observe it
    has loaded neither MuJoCo (nor its GL) nor Pinocchio, and the Observation came back."""
    code = (
        "import json, queue, sys\n"
        "from shared.fipa_codec.languages.l_ex import Observe\n"
        "from shared.fipa_codec.languages.l_sd import Observation\n"
        "from velma.executor.process import ExecutorProcess\n"
        "ex = ExecutorProcess(perception='camera', realtime=False, camera_idle_s=600.0)\n"
        "ex.start()\n"
        "box = queue.SimpleQueue()\n"
        "try:\n"
        "    ex.submit(Observe(objects=('jar',)), box.put)\n"
        "    got = box.get(timeout=120)\n"
        "finally:\n"
        "    ex.stop()\n"
        "assert isinstance(got, Observation) and [o.name for o in got.objects] == ['jar'], got\n"
        f"print(json.dumps([n for n in {HEAVY!r} if n in sys.modules]))\n"
    )
    assert loaded(code) == set()


PHYSICS_LIBRARIES = ("libmujoco", "libpinocchio", "libcoal", "libboost_python", "libeigenpy")
GL_LIBRARIES = ("libEGL", "libGL", "libOpenGL", "libOSMesa", "libglapi")


def libraries(pid: int) -> set[str]:
    """The file names of the shared libraries process ``pid`` maps (``/proc/PID/maps``)."""
    lines = Path(f"/proc/{pid}/maps").read_text().splitlines()
    return {line.rsplit("/", 1)[-1] for line in lines if ".so" in line.rsplit("/", 1)[-1]}


def named(found: set[str], prefixes: tuple[str, ...]) -> set[str]:
    """Those of ``found`` whose name begins with one of ``prefixes``."""
    return {f for f in found if f.startswith(prefixes)}


def test_the_library_check_sees_a_mapped_library() -> None:
    """The check can fail: this test process, once it imported Pinocchio, maps it."""
    import pinocchio  # noqa: F401

    assert named(libraries(os.getpid()), ("libpinocchio",))


def test_the_world_process_maps_mujoco_without_pinocchio_or_gl(tmp_path: Path) -> None:
    """``python -m velma.world`` as the launcher starts it, once it serves its link: MuJoCo's
    physics, no Pinocchio (the joints' order comes from MuJoCo's model, velma/control/joints.py
    ``robot_joints``) and no GL platform."""
    log = tmp_path / "world.stderr"
    with log.open("w") as stderr:
        world = subprocess.Popen(
            [sys.executable, "-m", "velma.world", "--run-dir", str(tmp_path), "--no-realtime"],
            cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
            stderr=stderr,
        )
    try:
        deadline = time.monotonic() + 120
        while link_name(tmp_path) is None and world.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # polls for the file the world writes once its link exists
        assert link_name(tmp_path) is not None, log.read_text()[-2000:]
        found = libraries(world.pid)
    finally:
        world.terminate()
        world.wait(30)
    assert named(found, ("libmujoco",))
    assert named(found, PHYSICS_LIBRARIES[1:] + GL_LIBRARIES) == set()


def test_the_loop_process_maps_its_physics_without_gl() -> None:
    """ag_ex's loop (velma/executor/process.py, here with the kitchen's physics in it as with
    ``ROCO_WORLD=loop``) computes with Pinocchio and MuJoCo, and renders nothing."""
    code = (
        "import json\n"
        "from pathlib import Path\n"
        "from velma.executor.process import ExecutorProcess\n"
        "ex = ExecutorProcess(perception='truth', realtime=False)\n"
        "ex.start()\n"
        "try:\n"
        "    maps = Path(f'/proc/{ex.pid}/maps').read_text().splitlines()\n"
        "finally:\n"
        "    ex.stop()\n"
        "print(json.dumps(sorted({m.rsplit('/', 1)[-1] for m in maps if '.so' in m.rsplit('/', 1)[-1]})))\n"
    )
    done = run_python(code)
    assert done.returncode == 0, done.stderr[-2000:]
    found = set(json.loads(done.stdout.strip().splitlines()[-1]))
    assert named(found, ("libmujoco",)) and named(found, ("libpinocchio",))
    assert named(found, GL_LIBRARIES) == set()
