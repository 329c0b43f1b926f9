"""A mutual-TLS deployment end to end: ``ROCO_TLS=1 roco run "pour the jar into the bowl"``
starts the router on ``tls/127.0.0.1:PORT`` with access control, every process authenticates
with its own certificate and password, and the pour succeeds (docs/security.md)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.report import build_report

pytestmark = [pytest.mark.slow, pytest.mark.fleet]


def test_tls_pour_succeeds(tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    env = dict(os.environ, ROCO_TLS="1")
    env.pop("ROCO_ACL", None)
    env.pop("ROCO_SECURITY", None)
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "run", "pour the jar into the bowl", "--runs-dir", str(runs)],
        capture_output=True,
        text=True,
        timeout=1200,
        env=env,
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert build_report(run_dir).header.succeeded is True
    router_log = (run_dir / "logs" / "router.stderr").read_text()
    assert "listening on tls/127.0.0.1:" in router_log and "access control from" in router_log
    acl = json.loads((run_dir / "security" / "acl.json").read_text())
    assert all(s["cert_common_names"] == [s["id"]] for s in acl["subjects"])
