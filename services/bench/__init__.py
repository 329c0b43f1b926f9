"""``roco bench``: roco's benchmarks (codec, messaging against raw Zenoh and SPADE,
knowledge, planning, fleet, task, scale), printed as tables and written to
``docs/benchmarks.md`` with the machine they were measured on (services/bench/runner.py; the
command: services/cli/bench.py)."""
