"""The whole case file: ``Case``, and loading it from YAML with errors that name the field."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Union

import yaml
from pydantic import Field, ValidationError, field_validator, model_validator

from dem.case.base import Vec3, StrictModel
from dem.case.imperfections import MAX_FRACTION, MAX_GAP_FRACTION, Imperfections
from dem.case.loadings import Loading, NoLoading, RecordLoading
from dem.case.material import Material
from dem.case.scene import SceneSpec
from dem.case.settings import RunSpec, SolverSpec


class Case(StrictModel):
    name: str = Field(min_length=1)
    description: str = ""
    scene: SceneSpec
    material: Material
    loading: Loading = Field(default_factory=lambda: NoLoading(type="none"))
    run: RunSpec
    solver: SolverSpec = Field(default_factory=SolverSpec)
    imperfections: Imperfections = Field(
        default_factory=Imperfections,
        description="imperfect dry joints (all zero: the perfect model); docs/imperfections.md")
    gravity: Union[float, Vec3] = Field(
        default=9.81,
        description="m/s2: a magnitude (pointing -z) or a vector in the table frame",
    )

    @field_validator("gravity", mode="before")
    @classmethod
    def _gravity_finite(cls, v):
        # before the union is tried: its branches would each report on their own ("a valid
        # number" for the vector)
        vals = v if isinstance(v, (list, tuple)) else [v]
        if all(isinstance(x, (int, float)) for x in vals) and \
                not all(math.isfinite(x) for x in vals):
            raise ValueError(f"must be a finite number or vector (m/s2), got {v}")
        return v

    @field_validator("gravity")
    @classmethod
    def _gravity(cls, v):
        if isinstance(v, (int, float)):
            if v < 0 or not math.isfinite(v):
                raise ValueError(f"gravity magnitude must be >= 0, got {v}")
        return v

    @model_validator(mode="after")
    def _imperfections_small(self) -> "Case":
        """Every imperfection length at most 10 % of the smallest brick dimension: beyond it the
        block is no longer the box whose inertia, contact patches and layout the model uses."""
        if not self.imperfections.any():
            return self
        smallest = self.smallest_brick_dimension()
        for name, value in self.imperfections.lengths().items():
            if value > MAX_FRACTION * smallest:
                raise ValueError(
                    f"imperfections.{name}: {value:g} m is more than {MAX_FRACTION:.0%} of the "
                    f"smallest brick dimension ({smallest:g} m)")
        imp = self.imperfections
        if imp.as_built():
            self._as_built_fits()
        return self

    def _as_built_fits(self) -> None:
        """The as-built fields act on builder bricks: a gap's largest draw (mean + 3 scatter)
        at most MAX_GAP_FRACTION of the shortest builder brick, a course's offset sigma within
        MAX_FRACTION of its smallest dimension (as the other imperfection lengths)."""
        from dem.builders import brick

        imp = self.imperfections
        bricks = [brick(spec.brick) for spec in (self.scene.wall, self.scene.facade,
                                                 self.scene.box_model) if spec is not None]
        if not bricks:
            name = next(n for n in ("corner_gap", "head_gap", "plumb")
                        if getattr(imp, n).any())
            raise ValueError(f"imperfections.{name}: acts on the bricks of scene.wall, "
                             f"scene.facade or scene.box_model; this scene has none")
        length = min(b.length for b in bricks)
        smallest = min(min(b.length, b.width, b.height) for b in bricks)
        for name in ("corner_gap", "head_gap"):
            gap = getattr(imp, name)
            if gap.largest() > MAX_GAP_FRACTION * length:
                raise ValueError(
                    f"imperfections.{name}: mean + 3 scatter = {gap.largest():g} m is more than "
                    f"{MAX_GAP_FRACTION:.0%} of the brick length ({length:g} m): a gap that "
                    f"large is a missing brick, not a loose joint")
        for i, sig in enumerate(imp.plumb.sigma):
            if sig > MAX_FRACTION * smallest:
                raise ValueError(
                    f"imperfections.plumb.sigma.{i}: {sig:g} m per course is more than "
                    f"{MAX_FRACTION:.0%} of the smallest brick dimension ({smallest:g} m)")

    @model_validator(mode="after")
    def _material_names_known(self) -> "Case":
        """Every material a block or builder part names is declared (dem.case.material)."""
        from dem.case.material import check_material_names

        check_material_names(self)
        return self

    def smallest_brick_dimension(self) -> float:
        """The smallest edge (m) of the scene's movable explicit blocks and builder bricks."""
        from dem.builders import brick

        edges = [min(b.size) for b in self.scene.blocks if not b.fixed]
        for spec in (self.scene.wall, self.scene.facade, self.scene.box_model):
            if spec is not None:
                b = brick(spec.brick)
                edges.append(min(b.length, b.width, b.height))
        return min(edges) if edges else min(min(b.size) for b in self.scene.blocks)

    def gravity_vector(self) -> list[float]:
        if isinstance(self.gravity, (int, float)):
            return [0.0, 0.0, -float(self.gravity)]
        return [float(x) for x in self.gravity]


# --------------------------------------------------------------------------------------------
# loading from files, with errors that name the field
# --------------------------------------------------------------------------------------------
class CaseError(Exception):
    """A case that cannot be used; the message names the bad field(s)."""


def format_validation_error(
    err: ValidationError, data=None, node=None, source: str | None = None
) -> str:
    """One line per problem naming the field path (and ``source:line`` when the YAML node tree is
    given), e.g. ``case.yaml:12: loading.frequency: Input should be greater than 0``.  The union
    tags pydantic inserts (``loading.shake.frequency``) are dropped; see :mod:`dem.case_errors`."""
    from dem.case_errors import format_errors

    return format_errors(err, Case, data=data, node=node, source=source)


def parse_case(data: dict, node=None, source: str | None = None) -> Case:
    try:
        return Case.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_validation_error(err, data=data, node=node, source=source)) from None


_YAML_KIND = {list: "a list", str: "a single text value", int: "a single number",
              float: "a single number", bool: "a single true/false"}


def read_case_yaml(path: str | Path, error: type[Exception] = None):
    """(data, YAML node tree) of a case file: the one reader of both case kinds (the DEM's and
    the two-body model's, dem.rocking.schema: one dialect, one set of messages).  Refused with ``error`` (default
    CaseError), each message ``FILE[:LINE]: what``: a file that cannot be read, YAML that does
    not parse, a key given twice in one mapping (yaml.safe_load would keep the last one), an
    empty file, a document that is not a mapping.  NaN and inf are refused by the models
    (dem.case.base.StrictModel)."""
    from dem.case_errors import DuplicateKeyError, compose

    error = error or CaseError
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise error(f"{path}: cannot read: {getattr(err, 'strerror', None) or err}") from None
    try:
        node = compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else f"{path}"
        raise error(f"{where}: not valid YAML: {err}") from None
    except DuplicateKeyError as err:
        where = f"{path}:{err.line}" if getattr(err, "line", None) else f"{path}"
        raise error(f"{where}: {err.message if hasattr(err, 'message') else err}") from None
    if data is None:
        raise error(f"{path}: the case file is empty (or only comments); a case is a YAML "
                    f"mapping: name:, scene:, material:, loading:, run: (cases/README.md)")
    if not isinstance(data, dict):
        kind = _YAML_KIND.get(type(data), type(data).__name__)
        raise error(f"{path}:{node.start_mark.line + 1}: the case must be a YAML mapping "
                    f"(key: value lines), got {kind}")
    return data, node


def key_line(node, key: str) -> int | None:
    """1-based line of a top-level key in a case file's node tree."""
    if isinstance(node, yaml.MappingNode):
        for k, _ in node.value:
            if getattr(k, "value", None) == key:
                return k.start_mark.line + 1
    return None


def load_case(path: str | Path) -> Case:
    path = Path(path)
    data, node = read_case_yaml(path)
    if "rocking" in data and "scene" in data:
        line = key_line(node, "rocking")
        raise CaseError(
            f"{path}:{line}: rocking: a case is either a DEM case (scene:, material:, ...; "
            f"dem run) or a two-body case (rocking:; dem rocking), not both: remove one of "
            f"'rocking:' and 'scene:' (line {key_line(node, 'scene')})")
    case = parse_case(data, node=node, source=str(path))
    ld = case.loading
    if isinstance(ld, RecordLoading) and ld.file is not None:
        f = Path(ld.file)
        ld.file = str(f if f.is_absolute() else path.parent / f)
        try:
            ld.samples()
        except ValueError as err:
            raise CaseError(f"{path}: loading.file: {err}") from None
    return case


def case_json_schema() -> str:
    """JSON schema of case files (``dem schema``; committed as ``cases/case.schema.json``).

    Editors with a YAML language server pick it up from a first line
    ``# yaml-language-server: $schema=<relative path>/case.schema.json``.
    """
    import json

    schema = Case.model_json_schema()
    schema = {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        **schema,
        "title": "dem-masonry case file",
    }
    return json.dumps(schema, indent=2) + "\n"
