"""Part 3b of ``roco bench``: JADE (the Java agent platform) on this machine, in the same run as
roco's messaging benchmark.

JADE comes from a local source tree (``--jade-home DIR`` or ``ROCO_JADE_HOME``), never from a
download: :func:`missing` says what is not there (the tree, ``javac``, ``java``) and the part is
then skipped. Then:

1. :func:`build_jade`: ``javac`` compiles the tree's ``src/jade`` (all but the IIOP message
   transport, ``jade/mtp/iiop``, which needs CORBA, gone from Java since 11, and is not used
   here) against the jars of its ``lib/``, into ``.bench/jade/KEY/classes`` of this repository
   (gitignored), KEY a digest of the tree's path, the newest modification time of its sources
   and jars, their number and ``javac -version``: one build per tree and JDK, kept. The tree's
   ``META-INF/MANIFEST.MF`` is copied beside the classes (JADE reads its version there).
2. roco's two agents, ``services/bench/java/RocoBenchResponder.java`` and
   ``RocoBenchInitiator.java``, compiled against it into the run's temporary folder.
3. Two JVMs (``java -Djava.awt.headless=true … jade.Boot``), all on 127.0.0.1: a main
   container (AMS, DF and the responder; ``-nomtp``: no HTTP message transport), then, once the
   responder has printed its ready line, a peripheral container with the initiator, the two
   talking over JADE's IMTP (LEAP, TCP) on free ports. The initiator prints the figures as one
   JSON line (the Java files say what each figure is).

Only the processes started here are ended, by PID (each in a session of its own), also when a
wait times out or a step fails. What is read from a JVM is bounded (:func:`read_line`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from services.bench.children import end_child
from services.bench.platform_figures import PlatformFigures
from services.fleet.launcher import free_port
from shared.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
AGENTS = Path(__file__).with_name("java")
"""roco's two benchmark agents, Java sources."""
CACHE = ROOT / ".bench" / "jade"
"""Where JADE's classes are compiled, one folder per source tree and JDK (gitignored)."""
JDK_PACKAGE = "Debian package default-jdk-headless"
READY = b"roco-bench-ready"
"""The responder's line once it is up (RocoBenchResponder.READY)."""
RESPONDER = "responder"
ANSWER_TIMEOUT_MS = 30_000
"""How long the initiator waits for any one answer before it gives up (ms)."""
LEFT_OUT = ("jade", "mtp", "iiop")
"""JADE's IIOP message transport: CORBA, which Java ≥ 11 no longer has; not used here."""


@dataclass
class JadeFigures(PlatformFigures):
    """What the JADE run gave (:class:`PlatformFigures`, ``versions`` of ``jade`` and
    ``java``), or ``skipped``: what is missing to run it."""

    skipped: str = ""


def missing(home: Path | None) -> str:
    """What the part needs and does not have, in words ('' when nothing is missing): the source
    tree, ``javac``, ``java``."""
    if home is None:
        return f"no JADE source tree (give --jade-home or set {Settings.env_name('jade_home')})"
    if not (home / "src" / "jade" / "core" / "Agent.java").is_file():
        return f"{home} is not a JADE source tree (no src/jade/core/Agent.java)"
    for tool in ("javac", "java"):
        if shutil.which(tool) is None:
            return f"no {tool} ({JDK_PACKAGE})"
    return ""


class BuildError(RuntimeError):
    """``javac`` failed or timed out; the message names its log."""


def _jars(home: Path) -> list[Path]:
    return sorted((home / "lib").rglob("*.jar"))


def _jade_sources(home: Path) -> list[Path]:
    src = home / "src"
    return [p for p in sorted((src / "jade").rglob("*.java")) if p.relative_to(src).parts[:3] != LEFT_OUT]


def _javac(args: Sequence[str], log: Path, timeout: float) -> None:
    """``javac ARGS``, its output to ``log``; raises BuildError when it fails or times out."""
    with log.open("ab") as out:
        try:
            done = subprocess.run(
                ["javac", *args], stdout=out, stderr=subprocess.STDOUT, timeout=timeout, check=False
            )
        except subprocess.TimeoutExpired:
            raise BuildError(f"javac did not finish within {timeout:.0f} s (log {log})") from None
    if done.returncode != 0:
        raise BuildError(f"javac failed (exit {done.returncode}; log {log})")


def build_key(home: Path) -> str:
    """The cache key of ``home``'s build (module docstring, step 1): 16 hex digits."""
    files = [*_jade_sources(home), *_jars(home)]
    newest = max((p.stat().st_mtime_ns for p in files), default=0)
    javac = subprocess.run(["javac", "-version"], capture_output=True, text=True, timeout=60, check=False)
    text = f"{home.resolve()}\n{newest}\n{len(files)}\n{(javac.stdout + javac.stderr).strip()}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def build_jade(home: Path, timeout: float = 1800.0) -> Path:
    """JADE's classes compiled from ``home`` (module docstring, step 1): the cached folder when
    there is one, else a new build (a minute or so on 2 cores). Two builds at once each compile
    into a temporary folder; the first renamed into place is kept. Raises BuildError."""
    done = CACHE / build_key(home)
    if (done / "classes").is_dir():
        return done / "classes"
    CACHE.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"{done.name}-", dir=CACHE))
    classes = work / "classes"
    classes.mkdir()
    listed = work / "sources.txt"
    listed.write_text("".join(f"{p}\n" for p in _jade_sources(home)))
    classpath = os.pathsep.join(str(j) for j in _jars(home))
    log = work / "javac.log"
    _javac(
        ["-nowarn", "-encoding", "UTF-8", "-cp", classpath, "-d", str(classes), f"@{listed}"], log, timeout
    )
    manifest = home / "META-INF" / "MANIFEST.MF"
    if manifest.is_file():
        (classes / "META-INF").mkdir(exist_ok=True)
        shutil.copyfile(manifest, classes / "META-INF" / "MANIFEST.MF")
    try:
        work.rename(done)
    except OSError:  # another build got there first: keep it
        shutil.rmtree(work, ignore_errors=True)
    return done / "classes"


def read_line(stream: IO[bytes], accept: Callable[[bytes], bool], timeout: float, limit: int) -> bytes | None:
    """The first whole line of ``stream`` (stripped) that ``accept`` takes, reading at most
    ``limit`` bytes within ``timeout`` s; None at the end of the stream, the timeout or the
    limit. Reads the file descriptor itself (``stream``'s buffer is not used)."""
    fd, buffered, read = stream.fileno(), b"", 0
    deadline = time.monotonic() + timeout
    while True:
        *lines, buffered = buffered.split(b"\n")
        for line in lines:
            if accept(line.strip()):
                return line.strip()
        left = deadline - time.monotonic()
        if left <= 0 or read >= limit or not select.select([fd], [], [], left)[0]:
            return None
        chunk = os.read(fd, min(1 << 16, limit - read))
        if not chunk:
            return None
        read += len(chunk)
        buffered += chunk


def _boot(classpath: str, args: list[str], work: Path, log: str) -> subprocess.Popen[bytes]:
    """A JVM running ``jade.Boot ARGS``: stdout piped, stderr (JADE's log) to ``work/log``."""
    with (work / log).open("wb") as err:
        return subprocess.Popen(
            ["java", "-Djava.awt.headless=true", "-cp", classpath, "jade.Boot", *args],
            cwd=work,
            stdout=subprocess.PIPE,
            stderr=err,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )


@dataclass(frozen=True)
class _Run:
    """One measure's counts."""

    warmup: int
    round_trips: int
    messages: int
    size: int


def _figures(got: dict[str, Any]) -> JadeFigures:
    """The initiator's JSON line as JadeFigures (its ``error`` when it has one)."""
    if "error" in got:
        return JadeFigures(error=f"the initiator: {got['error']}")
    return JadeFigures(
        samples_s=[ns / 1e9 for ns in got["round_trips_ns"]],
        count=int(got["count"]),
        sent=int(got["sent"]),
        span_s=int(got["span_ns"]) / 1e9,
        versions={k: str(got[k]) for k in ("jade", "java") if k in got},
    )


def _containers(
    classpath: str, work: Path, procs: list[subprocess.Popen[bytes]], run: _Run, timeout: float
) -> JadeFigures:
    """The main container, then the peripheral one (both kept in ``procs``): the initiator's
    figures, or the JadeFigures of the first step that failed."""
    port, local_port = free_port(), free_port()
    loopback = ["-host", "127.0.0.1", "-port", str(port), "-local-host", "127.0.0.1"]
    main = _boot(
        classpath,
        [*loopback, "-nomtp", "-name", "roco-bench", "-agents", f"{RESPONDER}:RocoBenchResponder"],
        work,
        "main.log",
    )
    procs.append(main)
    assert main.stdout is not None
    if read_line(main.stdout, lambda line: line == READY, 120, 1 << 20) is None:
        return JadeFigures(error=f"JADE's main container did not start within 120 s (log {work}/main.log)")
    counts = f"{RESPONDER},{run.warmup},{run.round_trips},{run.messages},{run.size},{ANSWER_TIMEOUT_MS}"
    peripheral = _boot(
        classpath,
        [
            "-container",
            *loopback,
            "-local-port",
            str(local_port),
            "-agents",
            f"initiator:RocoBenchInitiator({counts})",
        ],
        work,
        "peripheral.log",
    )
    procs.append(peripheral)
    assert peripheral.stdout is not None
    limit = (1 << 20) + 24 * run.round_trips  # a sample is at most 19 digits and a comma
    line = read_line(peripheral.stdout, lambda line: line.startswith(b"{"), timeout, limit)
    if line is None:
        return JadeFigures(
            error=f"the initiator printed no figures within {timeout:.0f} s (log {work}/peripheral.log)"
        )
    try:
        return _figures(json.loads(line))
    except (ValueError, KeyError, TypeError) as exc:
        return JadeFigures(error=f"the initiator's figures do not read: {exc}")


def how(home: Path, run: _Run) -> str:
    """How the part measures, in words (the report's bullet)."""
    return (
        f"{run.size}-character content; {run.round_trips} round trips after {run.warmup} warm-up ones "
        f"(the JIT's warm-up); {run.messages:,} informs after {run.warmup} warm-up ones; JADE compiled by "
        f"`javac` from the source tree {home}; a main container (AMS, DF, the responder) and a peripheral "
        "container (the initiator) in two JVMs, JADE's IMTP (LEAP) over TCP on 127.0.0.1, no message "
        "transport (`-nomtp`), no GUI, the JVMs' defaults otherwise"
    )


def measure(
    home: Path, warmup: int, round_trips: int, messages: int, size: int = 200, timeout: float = 300.0
) -> JadeFigures:
    """Run JADE's ping-pong (``round_trips`` after ``warmup`` warm-up ones) and one-way stream
    (``messages`` informs after ``warmup`` warm-up ones) with ``size``-character contents
    (module docstring); ``timeout``: the initiator's figures, at most (s). Never raises for
    JADE's own failures (they are returned in ``error``; a missing prerequisite in
    ``skipped``). The run's folder (logs) is removed when the measure succeeded."""
    run = _Run(warmup, round_trips, messages, size)
    why = missing(home)
    if why:
        return JadeFigures(skipped=why)
    settings = how(home, run)
    work = Path(tempfile.mkdtemp(prefix="roco-bench-jade-"))
    procs: list[subprocess.Popen[bytes]] = []
    got = JadeFigures(error="interrupted")
    try:
        classes = build_jade(home)
        agents = work / "agents"
        _javac(
            ["-cp", str(classes), "-d", str(agents), *map(str, sorted(AGENTS.glob("*.java")))],
            work / "javac.log",
            300,
        )
        classpath = os.pathsep.join([str(classes), str(agents), *map(str, _jars(home))])
        got = _containers(classpath, work, procs, run, timeout)
    except (BuildError, OSError) as exc:
        got = JadeFigures(error=f"could not run JADE: {exc}")
    finally:
        for proc in reversed(procs):
            with contextlib.suppress(OSError):
                end_child(proc)
        if not got.error:
            shutil.rmtree(work, ignore_errors=True)
    got.settings = settings
    return got


if __name__ == "__main__":  # a quick look: python -m services.bench.jade DIR
    fig = measure(Path(sys.argv[1]), 200, 500, 5000)
    print(
        fig.error or fig.skipped or f"{len(fig.samples_s)} round trips, {fig.rate:.0f} msg/s", file=sys.stderr
    )
