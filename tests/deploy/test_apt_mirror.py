"""scripts/apt_mirror.py: the Debian mirror scripts/build_image.sh gives debootstrap comes from
the host's apt configuration (sample trees of /etc/apt, no image is built)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "apt_mirror.py"


def apt_tree(tmp: Path, sources_list: str | None = None, **parts: str) -> Path:
    """A root with ``etc/apt/sources.list`` and ``sources.list.d/<name>`` files (``_`` in a
    keyword stands for ``.``)."""
    apt = tmp / "etc" / "apt"
    (apt / "sources.list.d").mkdir(parents=True)
    if sources_list is not None:
        (apt / "sources.list").write_text(sources_list)
    for name, text in parts.items():
        (apt / "sources.list.d" / name.replace("_", ".")).write_text(text)
    return tmp


def mirror(root: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--root", str(root), *args], capture_output=True, text=True, timeout=30
    )


def test_deb822_sources_of_a_debian_host(tmp_path: Path) -> None:
    """This machine's own layout: debian.sources with the security archive in a second stanza."""
    root = apt_tree(
        tmp_path,
        debian_sources="""Types: deb
# http://snapshot.debian.org/archive/debian/20250520T000000Z
URIs: http://mirror.site.example/debian/
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: http://mirror.site.example/debian-security
Suites: bookworm-security
Components: main
""",
    )
    out = mirror(root)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "http://mirror.site.example/debian"


def test_one_line_format_with_options_comments_and_source_entries(tmp_path: Path) -> None:
    root = apt_tree(
        tmp_path,
        sources_list="""# the site's mirror
deb-src http://src.example/debian bookworm main
deb http://security.debian.org/debian-security bookworm-security main
deb [arch=amd64 signed-by=/k.gpg] http://apt.site.example:3142/debian bookworm main contrib  # cached
""",
    )
    assert mirror(root).stdout.strip() == "http://apt.site.example:3142/debian"


def test_the_target_suite_wins_over_another_release(tmp_path: Path) -> None:
    """A trixie host's mirror is taken when nothing names bookworm; one that names bookworm
    (here in sources.list.d, read after sources.list) is preferred."""
    trixie = "deb http://trixie.example/debian trixie main\n"
    root = apt_tree(tmp_path / "a", sources_list=trixie)
    assert mirror(root).stdout.strip() == "http://trixie.example/debian"
    local = "deb file:///srv/mirror/debian bookworm main\n"
    root = apt_tree(tmp_path / "b", sources_list=trixie, local_list=local)
    assert mirror(root).stdout.strip() == "file:///srv/mirror/debian"


def test_disabled_stanzas_other_components_and_ubuntu_are_not_taken(tmp_path: Path) -> None:
    root = apt_tree(
        tmp_path,
        sources_list="deb http://archive.ubuntu.com/ubuntu jammy main restricted\n",
        a_sources="Types: deb\nURIs: http://off.example/debian\nSuites: bookworm\nComponents: main\n"
        "Enabled: no\n",
        b_sources="Types: deb\nURIs: http://nonfree.example/debian\nSuites: bookworm\nComponents: non-free\n",
        c_list="deb http://backports.example/debian bookworm-backports main\n",
    )
    out = mirror(root)
    assert out.returncode == 1 and out.stdout == ""
    assert "no Debian mirror" in out.stderr and "--mirror" in out.stderr and "DEBIAN_MIRROR" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_an_empty_apt_configuration_fails_with_one_line(tmp_path: Path) -> None:
    out = mirror(tmp_path)
    assert out.returncode == 1 and len(out.stderr.strip().splitlines()) == 1


def test_build_image_takes_no_mirror_written_into_it() -> None:
    """The script names no Debian host of its own: an option, the environment or apt."""
    text = (ROOT / "scripts" / "build_image.sh").read_text()
    assert "deb.debian.org" not in text
    assert "--mirror) MIRROR=$2" in text and "scripts/apt_mirror.py" in text
