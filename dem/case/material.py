"""``material:`` of a case file: the joints, given the way masonry engineers give them."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, ValidationError, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from dem.case.base import StrictModel

# Friction coefficients of dry masonry joints are 0.5-0.9 (thesis Section 4.2.3: 0.81), of the
# stickiest dry solid pairs (rubber on rough concrete) about 1-2.  mu = 10 is a friction angle of
# 84.3 deg: a joint that never slides in any scene this model can stand up (a block slides before
# it tips only if mu < b/h, and b/h > 10 is a plate lying flat).  Above it the number is a typo or
# a unit slip (1000 for 1.000, a percentage), so it is refused rather than run.
MAX_FRICTION = 10.0

# Named materials.  Every block has one: "brick" unless its entry (scene.blocks[k].material, or a
# builder's materials: {group: name}) names another; the table is "table".  Other names are
# declared in material.materials; material.pairs gives the joint constants of pairs of them.
DEFAULT_MATERIAL = "brick"
BUILTIN_MATERIALS = (DEFAULT_MATERIAL, "table")
MaterialName = Annotated[str, Field(min_length=1, max_length=40, pattern=r"^[A-Za-z][A-Za-z0-9_-]*$",
                                    description="a material name: brick, table or one declared "
                                    "in material.materials")]


def _errors(title: str, errs: list[tuple[tuple, str, object]]) -> ValidationError:
    """A ValidationError whose problems sit at the given locations (relative to the model that
    raises it), so that the case file's error names the field and its line."""
    return ValidationError.from_exception_data(title, [
        InitErrorDetails(type=PydanticCustomError("value_error", msg), loc=loc, input=value)
        for loc, msg, value in errs])


class PairMaterial(StrictModel):
    """The joint constants of one pair of named materials; a field left out takes the default
    pair's (the ``material:`` section's own fields; pairs with the table: base_friction)."""

    between: list[MaterialName] = Field(
        min_length=2, max_length=2,
        description="the two materials, e.g. [timber, brick] (order does not matter; the same "
        "name twice: blocks of one material against each other)")
    friction: float | None = Field(default=None, ge=0.0, le=MAX_FRICTION,
                                   description="Coulomb friction coefficient mu, -")
    normal_stiffness: float | None = Field(
        default=None, gt=0.0,
        description="kn, Pa/m (the hyperbolic law: kn0, the stiffness of the unloaded joint)")
    shear_stiffness: float | None = Field(
        default=None, gt=0.0,
        description="ks, Pa/m (default: material.shear_stiffness if given, else 0.4 kn)")
    damping: float | None = Field(default=None, ge=0.0, lt=1.0,
                                  description="viscous contact damping, fraction of critical")
    max_closure: float | None = Field(
        default=None, gt=0.0, description="d_max of the hyperbolic law for this pair, m")


class Material(StrictModel):
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
    # the new fields are left out of a case's dump (case.json, summary.json, the studies' resume
    # fingerprints and restart points) while they hold their defaults: the dump of every case
    # written before them stays the same
    normal_law: Literal["linear", "hyperbolic"] = Field(
        default="linear", exclude_if=lambda v: v == "linear",
        description="the joint's pressure p at closure d: 'linear' p = kn d, or 'hyperbolic' "
        "p = kn0 d / (1 - d/max_closure) (Bandis et al. 1983: soft at low stress, stiffening "
        "as the joint closes; normal_stiffness is then kn0; docs/engine.md section 4)")
    max_closure: float | None = Field(
        default=None, gt=0.0, exclude_if=lambda v: v is None,
        description="d_max, m: the largest closure of a hyperbolic joint (required by "
        "normal_law: hyperbolic)")
    closure_limit: float = Field(
        default=0.5, gt=0.0, lt=1.0, exclude_if=lambda v: v == 0.5,
        description="hyperbolic law: the time step is made stable for closures up to this "
        "fraction of max_closure (tangent stiffness kn0 / (1 - closure_limit)^2: 4 kn0 at 0.5); "
        "a joint that closes further stops the run (beyond_closure_limit: stop), -")
    beyond_closure_limit: Literal["stop", "tangent"] = Field(
        default="stop", exclude_if=lambda v: v == "stop",
        description="hyperbolic law: what a joint closing beyond closure_limit x max_closure "
        "does: 'stop' ends the run with an error; 'tangent' goes on along the law's tangent "
        "there (p = p(d_lim) + kt(d_lim) (d - d_lim): a capped hyperbolic law, the stiffness "
        "of the closed joint frozen at kt(d_lim); summary.json's hyperbolic_closure says how "
        "deep the deepest joint went; docs/engine.md section 4.2)")
    normal_damping: Literal["critical", "pair", "stiffness"] = Field(
        default="critical", exclude_if=lambda v: v == "critical",
        description="the normal dashpot of a joint: 'critical', damping x the pair's critical "
        "value, each contact point released as soon as its dashpot would pull harder than its "
        "spring pushes; 'pair', the same dashpot, an opening point held back by it as long as "
        "the joint as a whole still pushes (rocking impacts lose a little more than Housner's "
        "rigid block, as measured on rigid bases; docs/engine.md section 6); 'stiffness', "
        "beta kn per unit area with beta = damping_time and the pair's rule (Rayleigh's "
        "stiffness-proportional damping; damping then damps the shear only)")
    damping_time: float | None = Field(
        default=None, gt=0.0, le=1.0, exclude_if=lambda v: v is None,
        description="beta, s: the damping time of the stiffness-proportional normal dashpot "
        "(required by normal_damping: stiffness); a joint mode of frequency omega gets the "
        "damping ratio beta omega / 2")
    materials: list[MaterialName] = Field(
        default_factory=list, exclude_if=lambda v: not v,
        description="names of block materials besides 'brick' (every block's default) and "
        "'table', e.g. [timber, steel]; blocks take them with scene.blocks[k].material or a "
        "builder's materials: {group: name}")
    pairs: list[PairMaterial] = Field(
        default_factory=list, exclude_if=lambda v: not v,
        description="joint constants per pair of materials (later entries win); every other "
        "pair takes the fields above")

    @model_validator(mode="after")
    def _law_and_names(self) -> "Material":
        errs = []
        if self.normal_law == "hyperbolic":
            if self.max_closure is None:
                errs.append((("max_closure",), "normal_law: hyperbolic needs max_closure (m)",
                             None))
            if self.normal_stiffness == "rigid":
                errs.append((("normal_stiffness",), "'rigid' applies to the linear law only; "
                             "give kn0 (Pa/m) for the hyperbolic law", "rigid"))
        elif self.max_closure is not None:
            errs.append((("max_closure",), "applies to normal_law: hyperbolic only (the "
                         "default law is linear)", self.max_closure))
        if self.normal_damping == "stiffness" and self.damping_time is None:
            errs.append((("damping_time",), "normal_damping: stiffness needs damping_time "
                         "(beta, s)", None))
        elif self.normal_damping != "stiffness" and self.damping_time is not None:
            errs.append((("damping_time",), "applies to normal_damping: stiffness only (the "
                         "default dashpot is a fraction of critical, material.damping)",
                         self.damping_time))
        if self.normal_law != "hyperbolic" and self.beyond_closure_limit != "stop":
            errs.append((("beyond_closure_limit",), "applies to normal_law: hyperbolic only "
                         "(the default law is linear)", self.beyond_closure_limit))
        seen: set[str] = set()
        for k, name in enumerate(self.materials):
            if name in BUILTIN_MATERIALS or name in seen:
                errs.append((("materials", k), f"'{name}' is "
                             + ("built in" if name in BUILTIN_MATERIALS else "given twice"), name))
            seen.add(name)
        known = self.material_names()
        for k, pair in enumerate(self.pairs):
            for m, name in enumerate(pair.between):
                if name not in known:
                    errs.append((("pairs", k, "between", m), unknown_material(name, known), name))
            if pair.max_closure is not None and self.normal_law != "hyperbolic":
                errs.append((("pairs", k, "max_closure"), "applies to normal_law: hyperbolic "
                             "only", pair.max_closure))
        if errs:
            raise _errors("Material", errs)
        return self

    def material_names(self) -> list[str]:
        """Every material name a case may use: the built-in ones, then those declared."""
        return list(BUILTIN_MATERIALS) + list(self.materials)

    def ks(self, kn: float) -> float:
        """Shear stiffness, Pa/m, for the normal stiffness ``kn`` in use."""
        return self.shear_stiffness if self.shear_stiffness is not None else 0.4 * kn

    @property
    def mu_base(self) -> float:
        return self.base_friction if self.base_friction is not None else self.friction


def unknown_material(name: str, known: list[str]) -> str:
    return (f"unknown material '{name}' (known: {', '.join(known)}; declare it in "
            f"material.materials)")


def check_material_names(case) -> None:
    """Raise a ValidationError at each block or builder entry of ``case`` that names a material
    the case does not declare (material.materials, or the built-in brick and table)."""
    known = case.material.material_names()
    errs = []
    for k, block in enumerate(case.scene.blocks):
        name = getattr(block, "material", DEFAULT_MATERIAL)
        if name not in known:
            errs.append((("scene", "blocks", k, "material"), unknown_material(name, known), name))
    for key in ("wall", "facade", "box_model"):
        spec = getattr(case.scene, key)
        for group, name in (getattr(spec, "materials", None) or {}).items():
            if name not in known:
                errs.append((("scene", key, "materials", group), unknown_material(name, known),
                             name))
    if errs:
        raise _errors("Case", errs)
