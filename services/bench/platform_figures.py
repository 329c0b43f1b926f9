"""What a run of another agent platform beside roco gives (the ``spade`` and ``jade`` parts of
``roco bench``): round-trip samples and one pair's stream, measured by that platform's own
agents and read back from them."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class PlatformFigures:
    """Round-trip samples (s); the stream's ``count`` received at the responder of ``sent``,
    over ``span_s`` from its first to its last arrival (s); the ``versions`` measured; or
    ``error`` (why the measure failed). ``settings``: how it was measured, in words."""

    samples_s: list[float] = field(default_factory=list)
    count: int = 0
    sent: int = 0
    span_s: float = 0.0
    versions: dict[str, str] = field(default_factory=dict)
    error: str = ""
    settings: str = ""

    @property
    def rate(self) -> float:
        """Messages per second at the responder: (count − 1) over the first-to-last span."""
        return (self.count - 1) / self.span_s if self.span_s > 0 and self.count > 1 else 0.0
