"""``python -m velma.world`` (velma/world/main.py)."""

from velma.gl import never_renders

never_renders()  # the world steps the physics and renders nothing: MuJoCo loads no GL platform

from velma.world.main import main  # noqa: E402  (imports MuJoCo: after the choice above)

raise SystemExit(main())
