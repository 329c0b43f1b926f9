"""ag_ex's ledger (velma/executor/ledger.py) written into a synthetic run folder, for the tests
of the judges that read it (services/report/ledger.py, `roco chaos`)."""

from __future__ import annotations

from pathlib import Path

from velma.executor.ledger import LEDGER_FILE, Ledger


def ran(run_dir: Path, *runs: tuple[str, str, float, float | None], life: str = "100-aaaaaa") -> None:
    """Append to ``run_dir``'s ledger, as ag_ex process ``life``, each run (conversation-id,
    command, start s, end s or None: it never ended), ended ``ok``."""
    ledger = Ledger(run_dir / LEDGER_FILE, life=life)
    try:
        for conversation, command, start, end in runs:
            ledger.started(conversation, command, start)
            if end is not None:
                ledger.ended(conversation, command, end, "ok")
    finally:
        ledger.close()
