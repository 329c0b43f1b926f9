"""Check the manual against the code: every ``roco …`` command line that README.md and docs/
show names commands and options the CLI has, and every relative link reaches a file of the
repository and, when it names one, a heading of that file.

Where command lines are read (Markdown as GitHub renders it):

- fenced code blocks tagged ``sh``, ``bash``, ``shell``, ``zsh``, ``console``, ``text`` or
  untagged, and indented code blocks: a line is a command line when, after an optional ``$ ``
  prompt, environment assignments (``ROCO_ACL=0``) and ``sudo``/``env``, its first word is
  ``roco`` (or a path ending in ``/roco``) followed by a command-like word. Program output
  (``roco: succeeded …``, ``[ 1.7 s] …``) is thereby left alone. In ``console`` blocks only
  lines with a ``$ ``/``# `` prompt are commands. Lines ending in ``\\`` continue; ``;``,
  ``&&``, ``||``, ``&`` and a spaced ``|`` separate commands; ``#`` starts a comment.
- inline code spans (also across a line break) whose text is such a command line.

How the docs' conventions are read (never skipped wholesale):

- ``RUN``, ``NAME``, ``<timestamp>``, ``runs/<name>``: placeholders, counted as the
  positional arguments they stand for (too many for the command is an error);
- ``…`` or ``...``: arguments left out (a command left out, where a group expects one);
- ``[--opt VALUE]``, ``[RUN]``: optional groups, whose contents are checked as if given;
- ``a|b|c`` (no spaces around ``|``): alternatives, each checked; after a group's name
  (``roco spec show|check|verify RUN``) each alternative runs to the next ``|``; ``a/b/c``
  after a group's name and ``--x/--y`` are alternatives too (``--acl/--no-acl``).

The CLI is read from click's objects as ``typer.main.get_command`` builds them: a group's
``commands``; each command's ``params`` with ``opts`` and ``secondary_opts`` (the ``--no-x``
of ``--x/--no-x``), ``is_flag``/``count`` (an option without a value) and ``nargs``.

Anchors follow GitHub's rule (github-slugger): the heading's text as rendered, lower case;
every character but letters, marks, digits, ``_``, ``-`` and spaces dropped; spaces to
``-``; a repeated heading gets ``-1``, ``-2``, …
"""

from __future__ import annotations

import difflib
import re
import shlex
import subprocess
import unicodedata
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

MAX_DOC_BYTES = 2_000_000
"""A doc larger than this is reported, not read (the manual's pages are a few tens of kB)."""


@dataclass(frozen=True)
class Finding:
    """One thing wrong in a doc: ``path`` relative to the repository, 1-based ``line``."""

    path: str
    line: int
    message: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.message}"


# --- the CLI, as click sees it ------------------------------------------------------------


@dataclass(frozen=True)
class Option:
    """One option of a command: every spelling (``--acl``, ``--no-acl``), whether it takes a value."""

    names: tuple[str, ...]
    takes_value: bool


@dataclass
class Command:
    """A command or group of the CLI: its options by every name, how many positional
    arguments it takes (``None``: any number), and its sub-commands (a group) by name."""

    path: tuple[str, ...]
    options: dict[str, Option] = field(default_factory=dict)
    max_arguments: int | None = 0
    commands: dict[str, Command] = field(default_factory=dict)
    is_group: bool = False

    @property
    def shown(self) -> str:
        return " ".join(self.path)


HELP = Option(("--help",), takes_value=False)


def command_tree(click_command: object, path: tuple[str, ...] = ("roco",)) -> Command:
    """The tree of ``click_command`` (``typer.main.get_command(app)``), read by duck typing so
    that click's classes and typer's vendored copy of them both serve."""
    cmd = Command(path=path, options={"--help": HELP}, is_group=hasattr(click_command, "commands"))
    arguments: int | None = 0
    for param in getattr(click_command, "params", ()):
        if getattr(param, "param_type_name", "") == "option":
            names = (*param.opts, *param.secondary_opts)
            flag = bool(getattr(param, "is_flag", False) or getattr(param, "count", False))
            option = Option(tuple(names), takes_value=not flag)
            for name in names:
                cmd.options[name] = option
        elif arguments is not None:
            nargs = getattr(param, "nargs", 1)
            arguments = None if nargs < 0 else arguments + nargs
    cmd.max_arguments = arguments
    for name, sub in getattr(click_command, "commands", {}).items():
        cmd.commands[name] = command_tree(sub, (*path, name))
    return cmd


# --- reading a command line ----------------------------------------------------------------

ROCO = re.compile(r"^((\S*/)?bin/|\./)?roco$")
"""The program: ``roco``, ``.venv/bin/roco``, ``./roco`` (not a key such as ``roco/alive/a_hi``)."""
ENV_ASSIGNMENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*=")
WRAPPERS = frozenset({"sudo", "env", "time", "exec", "nohup"})
COMMAND_WORD = re.compile(
    r"""^\[?(
        -{1,2}[A-Za-z][\w-]*.*                     # an option
      | [a-z][a-z0-9_-]*([|/][a-z][a-z0-9_-]*)*\]?  # a command, or alternatives of commands
      | …|\.\.\.                                   # left out
      | [A-Z][A-Z0-9_]*\]?                          # a placeholder
      | <[^>]+>
    )$""",
    re.X,
)
PLACEHOLDER = re.compile(r"^([A-Z][A-Z0-9_]*|<[^>]+>)$")
ELLIPSIS = frozenset({"…", "..."})
NUMBER = re.compile(r"^-\d")


def split_commands(line: str) -> list[str]:
    """``line`` cut into the commands a shell would run, comments removed: at ``;``, ``&&``,
    ``||``, ``&`` and at a ``|`` with a space on either side (a pipe). A ``|`` between two
    words (``show|check``) is the docs' alternative and stays."""
    parts: list[str] = []
    current: list[str] = []
    quote = ""
    i = 0
    while i < len(line):
        ch = line[i]
        if quote:
            current.append(ch)
            if ch == "\\" and quote == '"' and i + 1 < len(line):
                current.append(line[i + 1])
                i += 1
            elif ch == quote:
                quote = ""
        elif ch == "\\" and i + 1 < len(line):
            current.append(line[i : i + 2])
            i += 1
        elif ch in "'\"":
            quote = ch
            current.append(ch)
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            break
        elif ch == ";" or (ch == "&" and line[i - 1 : i] != ">" and line[i + 1 : i + 2] != ">"):
            parts.append("".join(current))
            current = []
            if line[i + 1 : i + 2] == "&":
                i += 1
        elif ch == "|":
            before, after = line[i - 1 : i], line[i + 1 : i + 2]
            if after == "|" or not before or before.isspace() or not after or after.isspace():
                parts.append("".join(current))
                current = []
                if after == "|":
                    i += 1
            else:
                current.append(ch)
        else:
            current.append(ch)
        i += 1
    parts.append("".join(current))
    return [p.strip() for p in parts if p.strip()]


def roco_arguments(tokens: Sequence[str]) -> list[str] | None:
    """What follows ``roco`` in one command's words, or None when the command is not roco's
    (or is output that only starts with the word, as ``roco router: refused …``)."""
    i = 0
    while i < len(tokens) and (ENV_ASSIGNMENT.match(tokens[i]) or tokens[i] in WRAPPERS):
        wrapper = tokens[i] in WRAPPERS
        i += 1
        while wrapper and i < len(tokens) and tokens[i].startswith("-"):
            i += 1  # sudo -E
    if tokens[i : i + 1] in (["docker"], ["docker-compose"]) and "exec" in tokens:
        # docker compose … exec [options] SERVICE roco …: the command run in the container
        after = tokens.index("exec") + 1
        while after < len(tokens) and tokens[after].startswith("-"):
            after += 1
        i = after + 1
    if i >= len(tokens) or not ROCO.match(tokens[i]):
        return None
    rest = list(tokens[i + 1 :])
    if rest and not COMMAND_WORD.match(rest[0]):
        return None
    return rest


def _suggest(word: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(word, sorted(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def _alternatives(tokens: Sequence[str]) -> list[list[str]]:
    """``["show|check|verify", "RUN|new-agent", "NAME"]`` → ``[["show"], ["check"],
    ["verify", "RUN"], ["new-agent", "NAME"]]``: each alternative runs to the next ``|``."""
    alternatives: list[list[str]] = []
    current: list[str] = []
    for token in tokens:
        first, *others = token.split("|")
        current.append(first)
        for other in others:
            alternatives.append(current)
            current = [other]
    alternatives.append(current)
    return [[t for t in alt if t.strip("[]")] for alt in alternatives]


def check_arguments(
    words: Sequence[str], cmd: Command, reached: set[tuple[str, ...]] | None = None
) -> list[str]:
    """What is wrong with ``roco`` + ``words`` against ``cmd`` (the root): unknown commands,
    unknown options, more positional arguments than the command takes. Empty when all exist.
    The path of every command the words reach is added to ``reached``."""
    problems: list[str] = []
    _check(list(words), cmd, problems, set() if reached is None else reached)
    return problems


def _check(words: list[str], cmd: Command, problems: list[str], reached: set[tuple[str, ...]]) -> None:
    reached.add(cmd.path)
    positionals = 0
    i = 0
    while i < len(words):
        raw = words[i]
        token = raw.strip("[]")
        i += 1
        if not token:
            continue
        if token in ELLIPSIS:
            if cmd.is_group and positionals == 0:
                return  # a sub-command left out
            continue
        if token == "--":
            positionals += len(words) - i
            break
        if token.startswith("-") and not NUMBER.match(token):
            name, eq, _value = token.partition("=")
            takes_value = False
            for alternative in re.split(r"[|/]", name):
                option = cmd.options.get(alternative)
                if option is None:
                    spelled = alternative or name
                    problems.append(f"{cmd.shown} has no option {spelled}{_suggest(spelled, cmd.options)}")
                takes_value = takes_value or option is None or option.takes_value
            if takes_value and not eq and i < len(words):
                following = words[i].strip("[]")
                if not (following.startswith("-") and not NUMBER.match(following)):
                    i += 1
            continue
        if cmd.is_group and positionals == 0:
            if "|" in token:
                for alternative in _alternatives(words[i - 1 :]):
                    _check(alternative, cmd, problems, reached)
                return
            if "/" in token:
                for alternative in token.split("/"):
                    _check([alternative, *words[i:]], cmd, problems, reached)
                return
            if PLACEHOLDER.match(token):
                return  # a sub-command left to the reader
            sub = cmd.commands.get(token)
            if sub is None:
                known = ", ".join(sorted(cmd.commands)) or "none"
                problems.append(
                    f"{cmd.shown} has no command {token!r}{_suggest(token, cmd.commands)} "
                    f"(its commands: {known})"
                )
                return
            cmd = sub
            reached.add(cmd.path)
            continue
        positionals += 1
    if cmd.max_arguments is not None and positionals > cmd.max_arguments:
        problems.append(
            f"{cmd.shown} takes at most {cmd.max_arguments} argument(s), the doc gives {positionals}"
        )


# --- reading Markdown ------------------------------------------------------------------------

SHELL_BLOCKS = frozenset({"", "sh", "bash", "shell", "zsh", "console", "shell-session", "text", "txt"})
FENCE = re.compile(r"^( {0,3})(`{3,}|~{3,})\s*([^`\s]*)")
LIST_ITEM = re.compile(r"^(\s*)([-*+]|\d{1,9}[.)])(\s+)")
HEADING = re.compile(r"^ {0,3}(#{1,6})(?:\s+(.*?))?(?:\s+#+)?\s*$")


@dataclass(frozen=True)
class CodeLine:
    """A line of a code block: its 1-based number, its text, the block's info word
    (``"indented"`` for an indented block)."""

    number: int
    text: str
    kind: str


@dataclass(frozen=True)
class Prose:
    """A run of prose lines (a paragraph, a heading, a table row) and its first line's number."""

    first: int
    text: str


@dataclass
class Markdown:
    """A Markdown file cut into code lines and prose, as GitHub reads it."""

    code: list[CodeLine] = field(default_factory=list)
    prose: list[Prose] = field(default_factory=list)
    headings: list[tuple[int, str]] = field(default_factory=list)


def parse_markdown(text: str) -> Markdown:
    """Fenced and indented code blocks, prose paragraphs (a table row or heading on its own)
    and ATX headings of ``text``; HTML comments are dropped."""
    doc = Markdown()
    lines = text.splitlines()
    fence: tuple[str, int, str] | None = None  # char, length, info word
    in_comment = False
    paragraph: list[str] = []
    paragraph_first = 0
    list_indent = -1  # content indent of the list being read, -1 outside lists
    previous_blank = True

    def flush() -> None:
        nonlocal paragraph
        if paragraph:
            doc.prose.append(Prose(paragraph_first, "\n".join(paragraph)))
            paragraph = []

    for number, line in enumerate(lines, start=1):
        if fence is not None:
            closing = re.match(r"^ {0,3}(`{3,}|~{3,})\s*$", line)
            if closing and closing.group(1)[0] == fence[0] and len(closing.group(1)) >= fence[1]:
                fence = None
            else:
                doc.code.append(CodeLine(number, line, fence[2]))
            continue
        if in_comment or line.lstrip().startswith("<!--"):
            in_comment = "-->" not in line
            flush()
            continue
        opening = FENCE.match(line)
        if opening:
            flush()
            fence = (opening.group(2)[0], len(opening.group(2)), opening.group(3).lower())
            previous_blank = False
            continue
        if not line.strip():
            flush()
            previous_blank = True
            continue
        indent = len(line) - len(line.lstrip(" "))
        after_code = bool(doc.code) and doc.code[-1].kind == "indented" and doc.code[-1].number == number - 1
        if (previous_blank or after_code) and indent >= max(list_indent, 0) + 4 and not paragraph:
            doc.code.append(CodeLine(number, line, "indented"))
            continue
        previous_blank = False
        item = LIST_ITEM.match(line)
        if item:
            list_indent = len(item.group(1)) + len(item.group(2)) + len(item.group(3))
        elif indent == 0 and not paragraph:
            list_indent = -1
        heading = HEADING.match(line)
        if heading or line.lstrip().startswith("|"):
            flush()
            if heading:
                doc.headings.append((number, heading.group(2) or ""))
            doc.prose.append(Prose(number, line))
            continue
        if not paragraph:
            paragraph_first = number
        paragraph.append(line)
    flush()
    return doc


def code_spans(text: str) -> Iterator[tuple[int, int, str]]:
    """The inline code spans of a paragraph (CommonMark): (start offset, end offset, content
    with line breaks as spaces and the padding space stripped)."""
    i = 0
    while i < len(text):
        if text[i] == "\\":
            i += 2
            continue
        if text[i] != "`":
            i += 1
            continue
        run = len(text[i:]) - len(text[i:].lstrip("`"))
        j = i + run
        closing = re.compile(rf"(?<!`)`{{{run}}}(?!`)")
        match = closing.search(text, j)
        if match is None:
            i = j
            continue
        content = text[j : match.start()].replace("\n", " ")
        if content.startswith(" ") and content.endswith(" ") and content.strip():
            content = content[1:-1]
        yield i, match.end(), content
        i = match.end()


def _line_of(prose: Prose, offset: int) -> int:
    return prose.first + prose.text.count("\n", 0, offset)


@dataclass(frozen=True)
class CommandLine:
    """A ``roco`` command line found in a doc: where, as written, and what follows ``roco``
    (``None`` when shlex cannot read it)."""

    line: int
    text: str
    words: tuple[str, ...] | None
    error: str = ""


def _commands_in(text: str, line: int) -> Iterator[CommandLine]:
    for part in split_commands(text.replace("\\|", "|")):
        try:
            tokens = shlex.split(part)
        except ValueError as exc:
            if re.match(r"^(\S+=\S*\s+)*(\S*/)?roco\s", part):
                yield CommandLine(line, part, None, str(exc))
            continue
        words = roco_arguments(tokens)
        if words is not None:
            yield CommandLine(line, part, tuple(words))


def _joined(lines: Sequence[CodeLine]) -> Iterator[CommandLine]:
    """The command of a code line and the lines its trailing ``\\`` continued it with."""
    if lines:
        yield from _commands_in(" ".join(line.text for line in lines), lines[0].number)


def command_lines(text: str) -> list[CommandLine]:
    """Every ``roco`` command line of a Markdown text, in code blocks and inline code spans."""
    doc = parse_markdown(text)
    found: list[CommandLine] = []
    pending: list[CodeLine] = []
    for code in doc.code:
        if code.kind not in SHELL_BLOCKS and code.kind != "indented":
            continue
        body = code.text.strip()
        if code.kind == "console":
            if not body.startswith(("$ ", "# ")):
                continue
            body = body[2:]
        elif body.startswith("$ "):
            body = body[2:]
        if pending and pending[-1].number != code.number - 1:
            found.extend(_joined(pending))  # a continuation the block ended
            pending = []
        pending.append(CodeLine(code.number, body.removesuffix("\\"), code.kind))
        if not body.endswith("\\"):
            found.extend(_joined(pending))
            pending = []
    found.extend(_joined(pending))
    for prose in doc.prose:
        for start, _end, content in code_spans(prose.text):
            found.extend(_commands_in(content, _line_of(prose, start)))
    return sorted(found, key=lambda c: c.line)


def command_findings(text: str, path: str, cli: Command) -> list[Finding]:
    """Every ``roco`` command line of ``text`` (the file ``path``) that names a command or an
    option ``cli`` does not have, or that shlex cannot read."""
    findings: list[Finding] = []
    for cmd in command_lines(text):
        if cmd.words is None:
            problem = f"`{cmd.text}`: cannot read it as a command ({cmd.error})"
            findings.append(Finding(path, cmd.line, problem))
            continue
        for problem in check_arguments(cmd.words, cli):
            findings.append(Finding(path, cmd.line, f"`{cmd.text}`: {problem}"))
    return findings


# --- links -----------------------------------------------------------------------------------

INLINE_LINK = re.compile(
    r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]"  # [text], one level of nested brackets
    r"\(\s*(<[^>\n]*>|[^()\s]*(?:\([^()\s]*\)[^()\s]*)*)"  # (target
    r"(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)"  # "title")
)
REFERENCE_DEFINITION = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)", re.M)
HTML_LINK = re.compile(r"<(?:a|img)\s[^>]*?\b(?:href|src)=\"([^\"]*)\"", re.I)
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:|^//")
EXPLICIT_ANCHOR = re.compile(r"<a\s[^>]*?\b(?:name|id)=\"([^\"]+)\"", re.I)


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: ``"Two hosts: `roco hosts`"`` → ``"two-hosts-roco-hosts"``."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    kept = "".join(ch for ch in text.lower() if ch in " -_" or unicodedata.category(ch)[0] in "LMN")
    return kept.replace(" ", "-")


def anchors(text: str) -> set[str]:
    """Every anchor a Markdown file offers: its headings' (repeats numbered) and explicit
    ``<a name=…>``/``id=…`` ones."""
    doc = parse_markdown(text)
    seen: dict[str, int] = {}
    found: set[str] = set()
    for _line, heading in doc.headings:
        slug = github_anchor(heading)
        if slug in seen:
            seen[slug] += 1
            found.add(f"{slug}-{seen[slug]}")
        else:
            seen[slug] = 0
            found.add(slug)
    for prose in doc.prose:
        found.update(EXPLICIT_ANCHOR.findall(prose.text))
    return found


@dataclass(frozen=True)
class Link:
    line: int
    target: str


def links(text: str) -> list[Link]:
    """Every link target of a Markdown text outside code: inline links and images, reference
    definitions, HTML ``href``/``src``."""
    doc = parse_markdown(text)
    found: list[Link] = []
    for prose in doc.prose:
        blanked = list(prose.text)
        for start, end, _content in code_spans(prose.text):
            blanked[start:end] = [" " if ch != "\n" else ch for ch in prose.text[start:end]]
        plain = "".join(blanked)
        for pattern in (INLINE_LINK, REFERENCE_DEFINITION, HTML_LINK):
            for match in pattern.finditer(plain):
                target = match.group(1).strip("<>")
                found.append(Link(_line_of(prose, match.start()), target))
    return sorted(found, key=lambda link: link.line)


class Repository:
    """The files of a repository (tracked, or new and not ignored: ``git ls-files``; those the
    work tree still has), and the anchors of its Markdown files, read once each."""

    def __init__(self, root: Path) -> None:
        self.root = root.resolve()
        self._anchors: dict[Path, set[str]] = {}
        try:
            listed = subprocess.run(
                ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                cwd=self.root,
                capture_output=True,
                check=True,
                timeout=30,
            ).stdout.decode()
            # a tracked file deleted in the work tree (not yet committed) is none of its files
            listed_files = (self.root / p for p in listed.split("\0") if p)
            self.files: set[Path] | None = {f for f in listed_files if f.exists() or f.is_symlink()}
        except (OSError, subprocess.SubprocessError):
            self.files = None  # not a git checkout: the file system decides
        self.dirs = {d for f in self.files or () for d in f.parents}

    def has_file(self, path: Path) -> bool:
        return path.is_file() and (self.files is None or path in self.files)

    def has_dir(self, path: Path) -> bool:
        return path.is_dir() and (self.files is None or path in self.dirs)

    def anchors_of(self, path: Path) -> set[str]:
        if path not in self._anchors:
            self._anchors[path] = anchors(read_doc(path))
        return self._anchors[path]

    def relative(self, path: Path) -> str:
        return path.relative_to(self.root).as_posix()


def read_doc(path: Path) -> str:
    """A doc's text; ValueError when it is larger than MAX_DOC_BYTES."""
    size = path.stat().st_size
    if size > MAX_DOC_BYTES:
        raise ValueError(f"{path.name} is {size} bytes, over the {MAX_DOC_BYTES} a doc may have")
    return path.read_text(encoding="utf-8")


def link_findings(text: str, path: Path, repo: Repository) -> list[Finding]:
    """Every relative link of ``text`` (the file ``path`` of ``repo``) that reaches no file or
    folder of the repository, or whose ``#anchor`` is no heading of the Markdown file it names."""
    shown = repo.relative(path)
    findings: list[Finding] = []
    for link in links(text):
        if not link.target or SCHEME.match(link.target):
            continue
        target, _hash, anchor = link.target.partition("#")
        resolved = (path.parent / unquote(target)).resolve() if target else path
        if not resolved.is_relative_to(repo.root):
            findings.append(Finding(shown, link.line, f"link to {link.target}: outside the repository"))
            continue
        if repo.has_dir(resolved) and not anchor:
            continue
        if not repo.has_file(resolved):
            findings.append(
                Finding(shown, link.line, f"link to {link.target}: no such file in the repository")
            )
            continue
        if anchor and resolved.suffix == ".md":
            offered = repo.anchors_of(resolved)
            if unquote(anchor) not in offered:
                hint = _suggest(unquote(anchor), offered)
                findings.append(
                    Finding(
                        shown,
                        link.line,
                        f"link to {link.target}: {repo.relative(resolved)} has no heading "
                        f"with the anchor #{anchor}{hint}",
                    )
                )
    return findings


def manual(root: Path) -> list[Path]:
    """The files the check reads: README.md and every Markdown file under docs/."""
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
