"""The protocol roles are a package of small modules, one job each (services/runtime/roles/):
no module there is over ``MOST_LINES`` lines."""

from __future__ import annotations

from pathlib import Path

ROLES = Path(__file__).resolve().parents[2] / "services" / "runtime" / "roles"
MOST_LINES = 900


def too_long(folder: Path, most: int = MOST_LINES) -> dict[str, int]:
    """Each module of ``folder`` over ``most`` lines → its lines."""
    counts = {p.name: len(p.read_text().splitlines()) for p in sorted(folder.glob("*.py"))}
    return {name: n for name, n in counts.items() if n > most}


def test_no_module_of_the_roles_is_over_900_lines() -> None:
    assert (ROLES / "__init__.py").exists()
    assert too_long(ROLES) == {}


def test_a_module_over_the_bound_is_named(tmp_path: Path) -> None:
    """The planted fault: roles.py as it was, one module of 1,789 lines."""
    (tmp_path / "roles.py").write_text("x = 1\n" * 1789)
    (tmp_path / "declare.py").write_text("x = 1\n" * 900)
    assert too_long(tmp_path) == {"roles.py": 1789}
