"""The simulated Velma: model, control, perception, executor. Importing any module of it
chooses MuJoCo's off-screen GL platform first (velma/gl.py)."""

import velma.gl  # noqa: F401
