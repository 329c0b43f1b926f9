"""``python -m velma.world`` (velma/world/main.py)."""

from velma.world.main import main

raise SystemExit(main())
