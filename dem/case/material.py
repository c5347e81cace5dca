"""``material:`` of a case file: the joints, given the way masonry engineers give them."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field

from dem.case.base import _Strict

# Friction coefficients of dry masonry joints are 0.5-0.9 (thesis Section 4.2.3: 0.81), of the
# stickiest dry solid pairs (rubber on rough concrete) about 1-2.  mu = 10 is a friction angle of
# 84.3 deg: a joint that never slides in any scene this model can stand up (a block slides before
# it tips only if mu < b/h, and b/h > 10 is a plate lying flat).  Above it the number is a typo or
# a unit slip (1000 for 1.000, a percentage), so it is refused rather than run.
MAX_FRICTION = 10.0


class Material(_Strict):
    """Joint properties, given the way masonry engineers give them (3DEC style).

    Joint stiffness is per unit area of joint (Pa/m = N/m^3): a contact patch of area A closed by
    a gap d pushes back with kn * A * d.  It is converted to point springs by tributary area
    (see ``dem.engine.laws``).
    """

    friction: float = Field(ge=0.0, le=MAX_FRICTION,
                            description="Coulomb friction coefficient mu, - (at most 10, see "
                            "MAX_FRICTION)")
    normal_stiffness: Union[Literal["rigid"], Annotated[float, Field(gt=0.0)]] = Field(
        default=5.0e9,
        description="kn, Pa/m; or 'rigid': the kn that keeps the elastic offset of every block's "
        "tipping load factor at 0.5 % (dem/compliance.py; the run reports the kn chosen)")
    shear_stiffness: float | None = Field(
        default=None, gt=0.0, description="ks, Pa/m (default 0.4 kn)"
    )
    damping: float = Field(
        default=0.5, ge=0.0, lt=1.0,
        description="viscous contact damping, fraction of critical (0.5: near-plastic impacts "
        "of masonry units, normal restitution 0.16; see docs/engine.md)",
    )
    base_friction: float | None = Field(
        default=None, ge=0.0, le=MAX_FRICTION,
        description="friction against the table (default: friction; at most 10)"
    )

    def ks(self, kn: float) -> float:
        """Shear stiffness, Pa/m, for the normal stiffness ``kn`` in use."""
        return self.shear_stiffness if self.shear_stiffness is not None else 0.4 * kn

    @property
    def mu_base(self) -> float:
        return self.base_friction if self.base_friction is not None else self.friction
