"""``roco spec init NAME DIR``: a new system's folder, small and complete (docs/method.md).

It writes, in ``DIR`` (a folder that does not exist or is empty):

- ``NAME.toml``: a specification that ``roco spec check`` accepts: a requirement tree (R, with
  R1 "do what the person asks" and its property), one decomposition step splitting the system
  into ``ui`` and ``wk``, two agents (``a_ui``, which plays the person's role, and ``a_wk``),
  fipa-request on channel C1 and the system's own content language ``L_<NAME>``;
- the package ``NAME/``: its terms (``terms.py``), its names module (``names.py``, rendered
  as ``roco spec names`` does) and one folder per agent: ``a_ui`` turns each line the person
  says into a ``Task`` it asks ``a_wk`` to do and tells the outcome (services/runtime/person.py
  ``PersonFace``); ``a_wk`` agrees and answers ``Done``;
- ``tests/test_NAME.py``: a test that names R1, which ``roco spec trace`` reads.

So ``roco spec check``, ``verify-code``, ``roco up --spec``, ``roco send`` and ``roco spec
verify`` pass at once; the system grows from there with decomposition steps, ``roco spec
new-agent`` and ``roco spec names``. Nothing is written unless everything can be: the name is a
Python identifier of lower-case letters, digits and ``_``, not one of roco's packages, and the
folder is new or empty.
"""

from __future__ import annotations

import keyword
import re
from pathlib import Path

from services.spec.model import SpecError

_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")
TAKEN = frozenset({"services", "shared", "velma", "tests", "examples", "roco", "system"})
"""Names a system's package may not have: roco's own packages, and names that read as roco's."""

SPEC = """# {title}: a system designed with the paper's method (docs/method.md), written by `roco spec
# init`. 1. requirements, 2. binary decomposition, 3. agents, protocols, languages and channels.

system = "{title}"
start_order = ["a_wk", "a_ui"]

[[requirements]]
id = "R"
text = "do what a person asks"

[[requirements]]
id = "R1"
parent = "R"
text = "take a person's request, have it done and tell the outcome"
[[requirements.properties]]
text = "a task agreed to is done, in reply to it, and never failed (a failure is flagged live)"
exercised = 2
steps = [
  {{ name = "task", channel = "C1", protocol = "fipa-request", performative = "request", content = "Task" }},
  {{ channel = "C1", protocol = "fipa-request", performative = "agree", answers = "task" }},
  {failure_step},
  {done_step},
]

[[steps]]
number = 1
requirements = ["R", "R1"]
split = "{title}"
into = ["ui", "wk"]
tasks = {{ ui = "takes a person's requests and tells the outcome", wk = "does the tasks" }}
new_channels = [{{ number = 1, ends = ["ui", "wk"], transmits = "tasks and their outcome" }}]

[[agents]]
name = "a_ui"
group = "ui"
implementation = "{name}.ui.agent:Interface"
job = "interface: turns a person's line into a task, tells the outcome"
role = "person"

[[agents]]
name = "a_wk"
group = "wk"
implementation = "{name}.worker.agent:Worker"
job = "worker: does the tasks"

[protocols.fipa-request]  # FIPA SC00026

[languages.{language}]
ontology = "O_{title}"
terms = ["{name}.terms"]
description = "tasks and their outcome"

[[channels]]
name = "C1"
ends = ["a_ui", "a_wk"]
transmits = "tasks and their outcome"
  [[channels.protocols]]
  protocol = "fipa-request"
  initiator = "a_ui"
  languages = {{ {languages} }}
  contents = {{ request = ["Task"], inform = ["Done"], refuse = ["Refused"], failure = ["Refused"] }}
"""

TERMS = '''"""The content terms of {title}'s language {language} (its specification's
``[languages.{language}]``)."""

from __future__ import annotations

import msgspec


class Task(msgspec.Struct, frozen=True, tag="task", kw_only=True):
    """What a person asked, in their words."""

    text: str


class Done(msgspec.Struct, frozen=True, tag="done", kw_only=True):
    """A task done: what was done, in words."""

    text: str


class Refused(msgspec.Struct, frozen=True, tag="refused", kw_only=True):
    """Why a task is refused or failed, in words."""

    reason: str


TERMS = (Task, Done, Refused)
'''

UI = '''"""a_ui: turns each line a person says into a task for a_wk and tells the person the outcome.
It plays the person's role (``role = "person"``), so ``roco send`` talks to it."""

from __future__ import annotations

from {name}.names import C1, FIPA_REQUEST, {language}
from {name}.terms import Done, Refused, Task
from services.runtime.agent import FSM, MAX_LINE_CHARS, Agent, Behaviour, HumanInput, PersonFace, ReportKind
from services.runtime.roles import INITIATOR, Conversation, handles, initiator
from shared.fipa_codec import Performative


class Interface(Agent):
    name = "a_ui"
    ROLES = (initiator(C1, FIPA_REQUEST, {language}, reply_by_s=10.0),)

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("interact", self._interact, terminal=lambda: False, doc="lines into tasks")])

    def setup(self) -> None:
        self.person = PersonFace(self)
        self.person.open()

    def _interact(self) -> None:
        while self.r:
            event = self.r.popleft()
            if isinstance(event, HumanInput):
                self._ask(event)
        self.handle_received()

    def _ask(self, said: HumanInput) -> None:
        text = said.text.strip()
        if not text or len(text) > MAX_LINE_CHARS:
            self.person.tell(said.request_id, ReportKind.NOT_UNDERSTOOD, "say what to do, in one line")
            return
        self.roles.open(C1, FIPA_REQUEST, Task(text=text), data=said.request_id)

    @handles(FIPA_REQUEST, INITIATOR, Performative.AGREE)
    def _on_agree(self, conv: Conversation) -> None:
        self.person.tell(conv.data, ReportKind.ACCEPTED, "on it")

    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_done(self, conv: Conversation) -> None:
        done = conv.content
        self.person.tell(conv.data, ReportKind.SUCCEEDED, done.text if isinstance(done, Done) else "done")

    @handles(FIPA_REQUEST, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_not_done(self, conv: Conversation) -> None:
        why = conv.content.reason if isinstance(conv.content, Refused) else conv.reason or "not done"
        self.person.tell(conv.data, ReportKind.FAILED, why)
'''

WORKER = '''"""a_wk: does the tasks a_ui asks for (here: agrees and says it did it)."""

from __future__ import annotations

from {name}.names import C1, FIPA_REQUEST, {language}
from {name}.terms import Done, Refused, Task
from services.runtime.agent import FSM, Agent, Behaviour
from services.runtime.roles import PARTICIPANT, Conversation, handles, participant
from shared.fipa_codec import Performative


class Worker(Agent):
    name = "a_wk"
    ROLES = (participant(C1, FIPA_REQUEST, {language}),)

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("serve", self.handle_received, terminal=lambda: False, doc="do the tasks")])

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_task(self, conv: Conversation) -> None:
        task = conv.content
        if not isinstance(task, Task):
            conv.reply(Performative.REFUSE, Refused(reason="no task in the request"))
            return
        conv.reply(Performative.AGREE)
        conv.reply(Performative.INFORM, Done(text=f"done: {{task.text}}"))
'''

TEST = '''"""{title}'s own tests: ``roco spec trace`` reads their requirement marks."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SPEC = Path(__file__).resolve().parents[1] / "{name}.toml"


@pytest.mark.requirement("R1")
def test_the_specification_is_sound_and_the_code_matches_it() -> None:
    for tool in ("check", "verify-code"):
        done = subprocess.run(
            [sys.executable, "-m", "services.cli", "spec", tool, "--spec", str(SPEC)],
            capture_output=True,
            text=True,
        )
        assert done.returncode == 0, done.stdout + done.stderr
'''


def check_name(name: str) -> None:
    """Raise SpecError (one line) unless ``name`` can name a system's package."""
    if not _NAME.fullmatch(name) or keyword.iskeyword(name) or name in TAKEN:
        raise SpecError(
            f"{name!r} cannot name a system: lower-case letters, digits and '_', a letter first, at "
            f"most 40, not a Python keyword nor {', '.join(sorted(TAKEN))}"
        )


def files_of(name: str) -> dict[str, str]:
    """The files of system ``name`` (relative path → text). Raises SpecError for a name that
    cannot be a system's (:func:`check_name`)."""
    check_name(name)
    title = "".join(part.capitalize() for part in name.split("_") if part) or name
    language = f"L_{name.upper()}"
    performatives = ("request", "agree", "inform", "failure", "refuse", "cancel")
    fill = {
        "name": name,
        "title": title,
        "language": language,
        "languages": ", ".join(f'{p} = "{language}"' for p in performatives),
        "failure_step": '{ absent = true, channel = "C1", protocol = "fipa-request", '
        'performative = "failure", same_conversation = "task" }',
        "done_step": '{ channel = "C1", protocol = "fipa-request", performative = "inform", '
        'content = "Done", same_conversation = "task" }',
    }
    package_doc = f'"""The agents and content terms of {title} (its specification: {name}.toml)."""\n'
    return {
        f"{name}.toml": SPEC.format(**fill),
        f"{name}/__init__.py": package_doc,
        f"{name}/terms.py": TERMS.format(**fill),
        f"{name}/ui/__init__.py": '"""a_ui, the interface agent."""\n',
        f"{name}/ui/agent.py": UI.format(**fill),
        f"{name}/worker/__init__.py": '"""a_wk, the worker agent."""\n',
        f"{name}/worker/agent.py": WORKER.format(**fill),
        f"tests/test_{name}.py": TEST.format(**fill),
    }


def write_system(name: str, folder: Path) -> list[Path]:
    """Write system ``name`` into ``folder`` (made if missing) and render its names module from
    its specification; the files written. Raises SpecError, nothing written, for a name that
    cannot be a system's or a folder that exists and is not empty, and SpecError when the
    specification written does not load (then the files stay, for the error to be read)."""
    from services.spec.model import load
    from services.spec.render_names import names_file, write

    files = files_of(name)
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise SpecError(
            f"{folder}: not an empty folder; roco spec init writes a new system into a new folder"
        )
    written = []
    for relative, text in files.items():
        path = folder / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        written.append(path)
    spec_path = folder / f"{name}.toml"
    system = load(spec_path)
    names = names_file(spec_path, system)
    write(names, system)
    return [*written, names]
