"""The family of parts the suite measures and the `family` preset trains on.

A `Part` is a shape, a size S and a fit (the hole's clearance class, `constants.HOLE_FITS`).
`SUITE` spans the five shapes, sizes 10-80 mm and both fits; the parts marked held out are
never trained on (the `family` training preset draws from `TRAINED` alone), so the suite
measures them zero-shot and after transfer. `experiments/parts_suite.py` runs the suite.
"""

from __future__ import annotations

import dataclasses

from mjx_peg.world.parts import hole_scale_of


@dataclasses.dataclass(frozen=True)
class Part:
    """One part of the suite: its shape, size S (mm) and fit; its name reads them, e.g.
    'triangle-60-tight'."""

    shape: str
    size_mm: float
    fit: str  # "paper" or "tight" (constants.HOLE_FITS)
    held_out: bool = False

    @property
    def name(self) -> str:
        return f"{self.shape}-{self.size_mm:g}" + ("-tight" if self.fit == "tight" else "")

    @property
    def hole_scale(self) -> float:
        return hole_scale_of(self.shape, self.fit)

    def task_part(self) -> tuple[str, float, float]:
        """(shape, size in m, hole scale): an entry of TaskConfig.parts."""
        return self.shape, self.size_mm / 1000.0, self.hole_scale


SUITE = (
    Part("circle", 10, "paper"),
    Part("circle", 25, "tight"),
    Part("circle", 50, "paper"),
    Part("circle", 80, "tight"),
    Part("square", 30, "tight"),
    Part("square", 50, "paper"),
    Part("square", 70, "paper"),
    Part("triangle", 35, "paper"),
    Part("triangle", 50, "tight"),
    Part("hexagon", 40, "tight"),
    Part("hexagon", 60, "paper"),
    Part("rectangle", 25, "paper"),
    Part("rectangle", 50, "tight"),
    Part("triangle", 60, "tight", held_out=True),
    Part("hexagon", 20, "paper", held_out=True),
    Part("rectangle", 70, "tight", held_out=True),
    Part("square", 12, "paper", held_out=True),
)
TRAINED = tuple(p for p in SUITE if not p.held_out)
HELD_OUT = tuple(p for p in SUITE if p.held_out)


def by_name(name: str) -> Part:
    """The suite's part called `name` (e.g. 'triangle-60-tight'); KeyError lists them."""
    for part in SUITE:
        if part.name == name:
            return part
    raise KeyError(f"no part {name!r} in the suite: {', '.join(p.name for p in SUITE)}")
