"""Python code run in a fresh interpreter: a new process that inherits nothing this test
process imported, with the repository on its path."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def run_python(code: str, *, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """Run ``code`` (``python -c``) from the repository's root; its output as text. Raises
    subprocess.TimeoutExpired after ``timeout`` s; the exit code is the caller's to check."""
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
