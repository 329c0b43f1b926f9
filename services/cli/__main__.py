"""``python -m services.cli``: the ``roco`` console script, as the tests, the benchmarks and
the launcher start it (services/cli/__init__.py ``main``)."""

from services.cli import main

main()
