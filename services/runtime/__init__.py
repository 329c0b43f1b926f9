"""The agent runtime (paper §4): agents, behaviours, protocol roles, the transport.

Its hot path is compiled by mypyc when roco is installed (services/runtime/native.py); a
compiled module older than its source runs from the source instead.
"""

from pathlib import Path

from services.runtime.native import use_fresh_sources

use_fresh_sources(__name__, Path(__file__).parent)
