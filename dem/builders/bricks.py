"""Brick presets of the thesis (Section 3.3.1, 4.2.3) and custom bricks.

| preset | L x W x H (mm)  | mass (kg) | source                                                     |
|--------|-----------------|-----------|------------------------------------------------------------|
| small  | 105 x 50 x 35   | 0.336     | measured average (Section 4.2.3); density 1828.6 kg/m3      |
| large  | 152 x 75 x 50   | 1.042     | not given in the thesis: the small brick's density assumed |

Both have the shape ratio L : W : H = 6 : 3 : 2.  Friction (shear-box tests, Tables 3.1, 3.2):
0.81 for the small bricks, 0.56 for the large ones (a case sets it in ``material.friction``).
"""

from __future__ import annotations

from dataclasses import dataclass

SMALL_MASS = 0.336  # kg, Section 4.2.3
SMALL_SIZE = (0.105, 0.050, 0.035)  # m
SMALL_DENSITY = SMALL_MASS / (SMALL_SIZE[0] * SMALL_SIZE[1] * SMALL_SIZE[2])  # 1828.6 kg/m3
LARGE_SIZE = (0.152, 0.075, 0.050)  # m

#: friction coefficients measured in the thesis (for case files and documentation)
FRICTION = {"small": 0.81, "large": 0.56}


@dataclass(frozen=True)
class Brick:
    """A brick: length L (along a stretcher), width W, height H (m), mass (kg)."""

    length: float
    width: float
    height: float
    mass: float
    name: str = "custom"

    @property
    def volume(self) -> float:
        return self.length * self.width * self.height

    @property
    def density(self) -> float:
        return self.mass / self.volume

    def dims(self, laying: str) -> tuple[float, float, float]:
        """(length along the wall, thickness, course height) of a stretcher, m."""
        if laying == "flat":
            return self.length, self.width, self.height
        if laying == "on_edge":
            return self.length, self.height, self.width
        raise ValueError(f"laying must be 'flat' or 'on_edge', got {laying!r}")


PRESETS = {
    "small": Brick(*SMALL_SIZE, mass=SMALL_MASS, name="small"),
    "large": Brick(
        *LARGE_SIZE,
        mass=SMALL_DENSITY * LARGE_SIZE[0] * LARGE_SIZE[1] * LARGE_SIZE[2],
        name="large",
    ),
}


def brick(ref="small") -> Brick:
    """A :class:`Brick` from a preset name, a :class:`Brick`, a ``BrickSpec`` or a mapping
    ``{size: [L, W, H], mass | density}``."""
    if isinstance(ref, Brick):
        return ref
    if isinstance(ref, str):
        try:
            return PRESETS[ref]
        except KeyError:
            raise ValueError(f"unknown brick preset {ref!r}; presets: {sorted(PRESETS)}") from None
    if hasattr(ref, "model_dump"):
        ref = ref.model_dump()
    size = [float(x) for x in ref["size"]]
    mass = ref.get("mass")
    if mass is None:
        mass = float(ref["density"]) * size[0] * size[1] * size[2]
    return Brick(*size, mass=float(mass))
