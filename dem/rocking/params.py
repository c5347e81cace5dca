"""Parameters of the two-body rocking model and the geometry they fix: :class:`RockingParams`.

Geometry and conventions (derivation in ``docs/rocking_model.md``)
-------------------------------------------------------------------
Plane x-z, z up, x along the loading direction.  Part 1 (lower: thickness T, height H1, mass m1)
stands on the rigid base, Part 2 (upper: T, H2, m2) stands on Part 1.  Generalised coordinates are
the **absolute** angles theta1, theta2 (rad) of each part from the vertical, positive when the part's
top moves towards +x.  The integrator's state is ``y = (theta1, phi, omega1, omega_phi)`` with the
relative angle ``phi = theta2 - theta1`` (so that a joint that has just opened starts at exactly 0).

Derived constants (set once, in ``__post_init__``): R_i = sqrt(T^2 + H_i^2)/2 and alpha_i =
atan(T/H_i) (centre of part i seen from a bottom corner), I_Oi = m_i (T^2 + H_i^2)/3 about a bottom
corner and Ic_i about the centre, Fmax = mu N (the bound of the top friction; 0 for a co-moving top
load), mN = N/g (the mass of a co-moving top load), and ``load_geom[(s2, sigma)] = (Lp, gamma_p)``:
the load point p of the top load seen from Part 2's pivot, p - Q = Lp (sin psip, cos psip), psip =
theta2 + gamma_p.

Contact modes and patterns: :mod:`dem.rocking.patterns`; equations of motion:
:mod:`dem.rocking.equations`.  Units: SI (m, kg, s, N, rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(frozen=True)
class RockingParams:
    """Physical parameters of the two-block model (SI units).

    thickness T (m, both parts), h1/m1 lower part (m, kg), h2/m2 upper part, top_load N (N,
    vertical, on the top of Part 2), top_friction mu (-): the beams exert a horizontal friction of
    magnitude up to mu N on the load point; gravity g (m/s2); load_point "corner" (N acts on the
    raised top corner of Part 2, as in the thesis' equations of motion 5-9..5-14) or "centre" (on
    the middle of the top face, as in its uplift criterion 5-3); locked: the interface never opens
    (the two parts are one block, Pattern 3 only); top_contact "sliding" (the thesis: N fixed in
    space, friction up to mu N) or "co-moving" (N is a point mass N/g moving with the load point,
    no friction; ``mN`` its mass, kg).
    """

    thickness: float
    h1: float
    m1: float
    h2: float
    m2: float
    top_load: float = 0.0
    top_friction: float = 0.0
    gravity: float = 9.81
    load_point: str = "corner"
    locked: bool = False
    top_contact: str = "sliding"

    R1: float = field(init=False)
    R2: float = field(init=False)
    al1: float = field(init=False)
    al2: float = field(init=False)
    Ic1: float = field(init=False)
    Ic2: float = field(init=False)
    IO1: float = field(init=False)
    IO2: float = field(init=False)
    Fmax: float = field(init=False)
    mN: float = field(init=False)
    load_geom: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("thickness", "h1", "m1", "h2", "m2"):
            v = getattr(self, name)
            if not (v > 0 and math.isfinite(v)):
                raise ValueError(f"{name} must be > 0, got {v}")
        for name in ("top_load", "top_friction", "gravity"):
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise ValueError(f"{name} must be >= 0, got {v}")
        if self.load_point not in ("corner", "centre"):
            raise ValueError(f"load_point must be 'corner' or 'centre', got {self.load_point!r}")
        if self.top_contact not in ("sliding", "co-moving"):
            raise ValueError(f"top_contact must be 'sliding' or 'co-moving', got {self.top_contact!r}")
        if self.top_contact == "co-moving" and self.top_load > 0 and not self.gravity > 0:
            raise ValueError("a co-moving top load N needs gravity > 0 (its mass is N / g)")
        T = self.thickness
        s = object.__setattr__
        s(self, "R1", 0.5 * math.hypot(T, self.h1))
        s(self, "R2", 0.5 * math.hypot(T, self.h2))
        s(self, "al1", math.atan2(T, self.h1))
        s(self, "al2", math.atan2(T, self.h2))
        s(self, "Ic1", self.m1 * (T * T + self.h1 ** 2) / 12.0)
        s(self, "Ic2", self.m2 * (T * T + self.h2 ** 2) / 12.0)
        s(self, "IO1", self.m1 * (T * T + self.h1 ** 2) / 3.0)
        s(self, "IO2", self.m2 * (T * T + self.h2 ** 2) / 3.0)
        comoving = self.top_contact == "co-moving"
        s(self, "Fmax", 0.0 if comoving else self.top_friction * self.top_load)
        s(self, "mN", self.top_load / self.gravity if comoving and self.top_load > 0 else 0.0)
        geom = {}
        for s2 in (1, -1):
            for sig in (1, -1):
                if self.load_point == "corner":
                    u = -(sig + s2) * T / 2.0
                else:
                    u = -s2 * T / 2.0
                geom[(s2, sig)] = (math.hypot(u, self.h2), math.atan2(u, self.h2))
        s(self, "load_geom", geom)

    # convenience -------------------------------------------------------------------------
    @property
    def mass(self) -> float:
        return self.m1 + self.m2

    @property
    def height(self) -> float:
        return self.h1 + self.h2

    @property
    def comoving(self) -> bool:
        """True when the top load is a mass moving with the top (top_contact co-moving, N > 0)."""
        return self.mN > 0.0

    @property
    def ndof(self) -> int:
        """Velocities in maximal coordinates: two planar bodies, plus the beam's (x, z) if co-moving."""
        return 8 if self.comoving else 6

    @property
    def friction(self) -> bool:
        """True when the top friction can act (mu N > 0)."""
        return self.Fmax > 0.0

    def scales(self) -> dict:
        """Scales for tolerances: angular acceleration, angular velocity, force."""
        hmin = min(self.h1, self.h2, self.thickness)
        g = self.gravity if self.gravity > 0 else 9.81
        return {
            "acc": g / hmin,
            "vel": math.sqrt(g / hmin),
            "force": self.mass * g + self.top_load,
            "length": self.height,
        }
