"""The manual (README.md, docs/**/*.md) against the code: every ``roco …`` command line it
shows names commands and options of the real CLI (``services.cli:app``), every relative link
reaches a file of the repository and its anchor a heading of that file. The checker is
tests/docs/doccheck.py; the tests below also plant errors in docs and show that it finds them."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
import typer

from services.cli import app
from tests.docs import doccheck
from tests.docs.doccheck import Command, Finding, Repository

ROOT = Path(__file__).resolve().parents[2]
CLI: Command = doccheck.command_tree(typer.main.get_command(app))


@pytest.fixture(scope="module")
def repo() -> Repository:
    return Repository(ROOT)


def report(findings: list[Finding]) -> str:
    return f"{len(findings)} problem(s) in the manual:\n" + "\n".join(str(f) for f in findings)


def findings_in(text: str, path: str = "docs/planted.md") -> list[Finding]:
    return doccheck.command_findings(text, path, CLI)


# --- the manual as it is -------------------------------------------------------------------


def test_every_documented_command_and_option_exists() -> None:
    findings: list[Finding] = []
    for path in doccheck.manual(ROOT):
        text = doccheck.read_doc(path)
        findings += doccheck.command_findings(text, path.relative_to(ROOT).as_posix(), CLI)
    assert not findings, report(findings)


def test_every_relative_link_resolves(repo: Repository) -> None:
    findings: list[Finding] = []
    for path in doccheck.manual(ROOT):
        findings += doccheck.link_findings(doccheck.read_doc(path), path, repo)
    assert not findings, report(findings)


def test_the_check_reads_the_manual_s_commands() -> None:
    """Not a vacuous pass: the commands of README's table and of docs' code blocks are read."""
    seen: set[tuple[str, ...]] = set()
    for path in doccheck.manual(ROOT):
        for line in doccheck.command_lines(doccheck.read_doc(path)):
            assert line.words is not None
            seen.add(line.words[:2])
    assert len(seen) > 40
    assert {("run", "pour the jar into the bowl"), ("spec", "check"), ("fault", "kill")} <= seen


def test_every_command_of_the_cli_is_in_the_manual() -> None:
    """Each command and sub-command of ``roco`` appears in the manual at least once."""
    documented: set[tuple[str, ...]] = set()
    for path in doccheck.manual(ROOT):
        for line in doccheck.command_lines(doccheck.read_doc(path)):
            doccheck.check_arguments(line.words or (), CLI, documented)

    def paths(cmd: Command) -> list[tuple[str, ...]]:
        return [cmd.path, *(p for sub in cmd.commands.values() for p in paths(sub))]

    missing = [" ".join(p) for p in paths(CLI) if p not in documented]
    assert not missing, f"commands the manual never shows: {', '.join(missing)}"


# --- the checker finds what is wrong ---------------------------------------------------------


def test_a_misspelt_option_in_a_copy_of_a_doc_is_found(tmp_path: Path) -> None:
    doc = tmp_path / "faults.md"
    shutil.copy(ROOT / "docs" / "faults.md", doc)
    text = doc.read_text()
    assert "--duplicate 0.05" in text
    doc.write_text(text.replace("--duplicate 0.05", "--duplicat 0.05", 1))
    line = text[: text.index("--duplicate 0.05")].count("\n") + 1

    findings = findings_in(doc.read_text(), "docs/faults.md")

    assert [(f.path, f.line) for f in findings] == [("docs/faults.md", line)]
    assert "roco fault msg has no option --duplicat (did you mean --duplicate?)" in findings[0].message
    assert str(findings[0]).startswith(f"docs/faults.md:{line}: `roco fault msg C4 --drop 0.1 --duplicat")


def _plant(text: str, first_line: int, word: str, after: str = "") -> str | None:
    """``text`` with the first ``word`` (a whole word, following ``after`` and white space when
    given) on ``first_line`` or the three lines after it (a span may run on) misspelt as
    ``word + "q"``; None when it is not there."""
    lines = text.splitlines(keepends=True)
    start = sum(len(line) for line in lines[: first_line - 1])
    end = sum(len(line) for line in lines[: first_line + 3])
    lead = rf"({re.escape(after)}\s+)" if after else "()"
    pattern = re.compile(rf"(?<![\w-]){lead}{re.escape(word)}(?![\w-])")
    planted, n = pattern.subn(rf"\g<1>{word}q", text[start:end], count=1)
    return text[:start] + planted + text[end:] if n else None


def test_a_misspelling_planted_in_any_command_line_of_the_manual_is_found() -> None:
    """Each command line of the manual in turn, its first option (or else its command) misspelt
    in a copy of its file: the check names that line and that word."""
    planted = 0
    for path in doccheck.manual(ROOT):
        text = doccheck.read_doc(path)
        for line in doccheck.command_lines(text):
            words = [w.strip("[]") for w in line.words or ()]
            options = [re.split(r"[=|/]", w)[0] for w in words if w.startswith("--")]
            if options:
                word, after, problem = options[0], "", f"has no option {options[0]}q"
            elif words and re.fullmatch(r"[a-z][a-z-]*", words[0]):
                word, after, problem = words[0], "roco", f"roco has no command '{words[0]}q'"
            else:
                continue
            copy = _plant(text, line.line, word, after)
            assert copy is not None, f"{path}:{line.line}: {word} not found to plant"
            findings = findings_in(copy, path.name)
            assert any(f.line == line.line and problem in f.message for f in findings), (
                f"{path.name}:{line.line}: `{line.text}` with {word}q planted: {findings}"
            )
            planted += 1
    assert planted > 100


@pytest.mark.parametrize(
    ("planted", "problem"),
    [
        ("`roco wtach`", "roco has no command 'wtach'"),
        ("`roco run … --quite`", "roco run has no option --quite (did you mean --quiet?)"),
        ("`roco fault net SERVICE [--delay S] [--partition|--heel]`", "has no option --heel"),
        ("`roco fault net SERVICE [--delay S [--los P]]`", "has no option --los"),
        ("`roco spec show|check|verfy RUN|new-agent NAME`", "roco spec has no command 'verfy'"),
        ("`roco fault msg|nett|clear`", "roco fault has no command 'nett'"),
        ("`roco down/stauts`", "roco has no command 'stauts'"),
        ("`roco deploy router OUT NAME --ip/--dsn …`", "roco deploy router has no option --dsn"),
        ("`roco up --tls/--no-tsl`", "roco up has no option --no-tsl"),
        ("`roco up --realtime yes`", "roco up takes at most 0 argument(s), the doc gives 1"),
        ("`roco report RUN OTHER`", "roco report takes at most 1 argument(s), the doc gives 2"),
        ("`ROCO_ACL=0 sudo -E .venv/bin/roco scenaro pour`", "roco has no command 'scenaro'"),
        ("`docker compose -p roco exec a_hi roco sned hi`", "roco has no command 'sned'"),
        ("```sh\nroco up && roco sned hi | tee log\n```", "roco has no command 'sned'"),
        ("```console\n$ roco sniff --chanel C1\nroco: 0 communicates\n```", "has no option --chanel"),
        ("```\nroco chaos --seed 1 \\\n    --kind kill   # each agent\n```", "chaos has no option --kind"),
        ("    roco status --credential DIR", "roco status has no option --credential"),
        ('`roco send "what are you doing?`', "cannot read it as a command"),
    ],
)
def test_a_planted_error_is_found(planted: str, problem: str) -> None:
    text = f"# A page\n\nSome prose first.\n\n{planted}\n"
    findings = findings_in(text)
    assert len(findings) == 1, findings
    assert findings[0].line == (6 if planted.startswith("```") else 5)  # a fence's next line
    assert problem in findings[0].message


def test_a_span_across_a_line_break_is_read_and_placed_on_its_first_line() -> None:
    text = "One line,\nand `roco chaos --hosts --services link\n--cut 35,35 --gapp 3,3` in prose.\n"
    findings = findings_in(text)
    assert [(f.line, "--gapp" in f.message) for f in findings] == [(2, True)]


@pytest.mark.parametrize(
    "good",
    [
        "`roco`",
        "`roco view [RUN]`",
        "`roco view runs/<timestamp>`",
        "`roco spec show|check|deadlock|verify-code|verify RUN|new-agent NAME`",
        "`roco spec show\\|check\\|deadlock` in a table cell",
        "`roco spec …`",
        "`roco fault msg … --router tcp/127.0.0.1:7447`",
        "`roco fault net SERVICE [--delay S] [--loss P] [--partition|--heal]`",
        "`roco fault msg CHANNEL [--drop P] [--delay S [--delay-p P]] [--reorder P [--hold S]]`",
        "`roco deploy router OUT router_<host> --ip/--dns …`",
        "`roco down/status/send`",
        "`roco up --acl/--no-acl --seed=3`",
        '`roco up; roco send "stop"; roco down`',
        "`roco chaos --hosts [--delay-ms 20 --jitter-ms 5 --loss-pct 1]`",
        "`roco bench --quick --only messaging,spade`",
        '`ROCO_FAULTS=\'{"seed": 1}\' roco run "pour the jar into the bowl"`',
        "`.venv/bin/roco doctor`",
    ],
)
def test_the_docs_conventions_are_understood(good: str) -> None:
    findings = findings_in(f"Prose with {good}.\n")
    assert not findings, findings


def test_output_and_other_languages_are_not_read_as_commands() -> None:
    text = """\
```text
[    1.7 s] all agents alive after 0.9 s
roco: succeeded in 16.8 s wall; 281 communicates
roco router: refused #1: a_pl put (ingress) roco/fipa/C1/a_co/a_ta
```

```python
subprocess.run(["roco", "wtach"])
```

```toml
command = "roco wtach"
```

The key `roco/alive/a_hi`, the log line `roco router: refused #1`, the project `-p roco`:
`docker compose -f deploy/compose.yaml -p roco up -d`.
"""
    assert doccheck.command_lines(text) == []


# --- links -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("heading", "anchor"),
    [
        ("Two hosts on one machine: `roco hosts`", "two-hosts-on-one-machine-roco-hosts"),
        ("a_hi — human interface (`services/agents/hi/`)", "a_hi--human-interface-servicesagentshi"),
        ("Walk-through: adding an agent", "walk-through-adding-an-agent"),
        ("Recorder and router faults", "recorder-and-router-faults"),
        ("[Linked](x.md) *and* **bold**, 2×", "linked-and-bold-2"),
        ("Größe über ±2 cm", "größe-über-2-cm"),
    ],
)
def test_anchors_follow_github_s_rule(heading: str, anchor: str) -> None:
    assert doccheck.github_anchor(heading) == anchor


def test_a_broken_link_and_a_broken_anchor_are_found(tmp_path: Path) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "b.md").write_text("# B\n\n## Same\n\n## Same\n\n```sh\n# not a heading\n```\n")
    page = tmp_path / "docs" / "a.md"
    page.write_text(
        "# A\n\n"
        "[fine](b.md), [fine too](b.md#same-1), [folder](../docs/), [site](https://example.org/x.md)\n"
        "[missing](c.md) and\n"
        "[no heading](b.md#not-a-heading) and ![picture](img/none.png)\n\n"
        "`[in code](nowhere.md)` and [here](#a) and [here](#b)\n\n"
        "[ref]: ../../outside.md\n"
    )
    findings = doccheck.link_findings(page.read_text(), page, Repository(tmp_path))
    assert [(f.line, f.message.split(":")[0]) for f in findings] == [
        (4, "link to c.md"),
        (5, "link to b.md#not-a-heading"),
        (5, "link to img/none.png"),
        (7, "link to #b"),
        (9, "link to ../../outside.md"),
    ]
    assert "docs/b.md has no heading with the anchor #not-a-heading" in findings[1].message
    assert "no such file in the repository" in findings[0].message


def test_a_broken_link_planted_in_a_real_doc_is_found(repo: Repository) -> None:
    page = ROOT / "docs" / "README.md"
    text = doccheck.read_doc(page) + "\n[x](agents.md#no-such-section) and [y](agentz.md)\n"
    findings = doccheck.link_findings(text, page, repo)
    assert [f.message for f in findings] == [
        "link to agents.md#no-such-section: docs/agents.md has no heading with the anchor #no-such-section",
        "link to agentz.md: no such file in the repository",
    ]


def test_a_git_ignored_file_is_not_a_file_of_the_repository(tmp_path: Path) -> None:
    if shutil.which("git") is None:
        pytest.skip("needs git (apt-get install git): it says which files are ignored")
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    (tmp_path / ".gitignore").write_text("runs/\n")
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "report.md").write_text("# A run\n")
    page = tmp_path / "README.md"
    page.write_text("[kept](.gitignore) [a run](runs/report.md) [runs](runs/)\n")
    findings = doccheck.link_findings(page.read_text(), page, Repository(tmp_path))
    assert [f.message.split(":")[0] for f in findings] == ["link to runs/report.md", "link to runs/"]


# --- the CLI as the checker reads it ------------------------------------------------------


def test_the_cli_tree_has_click_s_commands_options_and_arguments() -> None:
    up = CLI.commands["up"]
    assert up.options["--acl"] is up.options["--no-acl"]
    assert not up.options["--acl"].takes_value and up.options["--port"].takes_value
    assert up.max_arguments == 0 and CLI.commands["report"].max_arguments == 1
    assert CLI.commands["fault"].is_group and "kill" in CLI.commands["fault"].commands
    assert CLI.commands["spec"].commands["new-agent"].path == ("roco", "spec", "new-agent")
