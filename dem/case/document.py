"""The whole case file: ``Case``, and loading it from YAML with errors that name the field."""

from __future__ import annotations

import functools
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
        elif any(v) and v[2] >= 0:
            # the table is the plane z = 0 with z up: a gravity without a downward component
            # lifts the blocks off it (or slides them sideways forever); a tilt turns the
            # table, not gravity (dem.loading)
            raise ValueError(
                f"gravity {list(v)} m/s2 does not point down (its z component must be "
                f"negative: z is up, the table is the plane z = 0); give a magnitude "
                f"(9.81) or a vector such as [0, 0, -9.81]")
        return v

    @model_validator(mode="after")
    def _tilt_needs_gravity(self) -> "Case":
        """A tilt turns the table under gravity: without gravity nothing drives the blocks and
        the load factor (tan of the tilt angle) means nothing."""
        if self.loading.type == "tilt" and not any(self.gravity_vector()):
            raise ValueError(
                "gravity: a tilt without gravity (gravity 0): tilting the table moves nothing, "
                "and its load factor (tan of the angle at collapse) is undefined; give "
                "gravity: 9.81")
        return self

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
    def _scatter_needs_builder_bricks(self) -> "Case":
        """size_scatter scatters the builders' bricks (dem.builders.scatter): explicit blocks
        keep the sizes the file gives them, so on a scene of explicit blocks alone it would be
        accepted and do nothing."""
        sc = self.scene
        if any(v > 0 for v in self.imperfections.size_scatter) and \
                sc.wall is None and sc.facade is None and sc.box_model is None:
            raise ValueError(
                "imperfections.size_scatter: applies to the bricks of a builder (scene.wall, "
                "facade, box_model) only; the explicit blocks of scene.blocks keep the sizes "
                "given, so it would change nothing here: give the sizes you want in "
                "scene.blocks, or leave size_scatter out")
        return self

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
    anchor that contains itself or aliases that expand beyond reason (dem.case_errors), an
    empty file, a document that is not a mapping.  NaN and inf are refused by the models
    (dem.case.base.StrictModel).  The file is parsed once (libyaml's loader where there is one)
    and the result kept for the next reader of the same unchanged file (dem check reads it to
    dispatch, to validate and to name lines)."""
    error = error or CaseError
    path = Path(path)
    try:
        st = path.stat()
        data, node = _parsed(str(path), st.st_mtime_ns, st.st_size)
    except (OSError, UnicodeDecodeError) as err:
        raise error(f"{path}: cannot read: {getattr(err, 'strerror', None) or err}") from None
    except _ParseError as err:
        raise error(f"{path}{err.where}: {err.message}") from None
    if data is None:
        raise error(f"{path}: the case file is empty (or only comments); a case is a YAML "
                    f"mapping: name:, scene:, material:, loading:, run: (cases/README.md)")
    if not isinstance(data, dict):
        kind = _YAML_KIND.get(type(data), type(data).__name__)
        raise error(f"{path}:{node.start_mark.line + 1}: the case must be a YAML mapping "
                    f"(key: value lines), got {kind}")
    return data, node


class _ParseError(Exception):
    def __init__(self, message: str, line: int | None = None):
        super().__init__(message)
        self.message, self.where = message, f":{line}" if line else ""


@functools.lru_cache(maxsize=2)
def _parsed(path: str, mtime_ns: int, size: int):
    """(data, node) of the file at ``path`` as it was at (mtime_ns, size): the cache key."""
    from dem.case_errors import AliasError, DuplicateKeyError, load

    text = Path(path).read_text()
    try:
        node, data = load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        raise _ParseError(f"not valid YAML: {yaml_problem(err)}",
                          mark.line + 1 if mark is not None else None) from None
    except (DuplicateKeyError, AliasError) as err:
        raise _ParseError(err.message, err.line) from None
    except RecursionError:
        raise _ParseError("nested too deeply to be read (a case is a few levels deep)") from None
    return data, node


def yaml_problem(err: yaml.YAMLError) -> str:
    """A YAML syntax error in one line: what is wrong and where (PyYAML's message spans 3-7 lines
    with the offending text and a caret)."""
    problem = getattr(err, "problem", None)
    if not problem:
        return " ".join(str(err).split())
    mark = getattr(err, "problem_mark", None)
    context = getattr(err, "context", None)
    text = problem + (f" (column {mark.column + 1})" if mark is not None else "")
    if context:
        cmark = getattr(err, "context_mark", None)
        text += f", {context}" + (f" (line {cmark.line + 1})" if cmark is not None else "")
    return text


def key_line(node, key: str) -> int | None:
    """1-based line of a top-level key in a case file's node tree."""
    if isinstance(node, yaml.MappingNode):
        for k, _ in node.value:
            if getattr(k, "value", None) == key:
                return k.start_mark.line + 1
    return None


def explicit_block_count(data) -> int:
    """The number of entries of ``scene.blocks`` in a case's data (0 where there is none)."""
    scene = data.get("scene") if isinstance(data, dict) else None
    blocks = scene.get("blocks") if isinstance(scene, dict) else None
    return len(blocks) if isinstance(blocks, list) else 0


def load_case(path: str | Path, max_blocks: int | None = None) -> Case:
    """The validated case of the file at ``path`` (CaseError naming the field and line).
    ``max_blocks`` (default: dem.environment.max_blocks_default): a scene listing more explicit
    blocks is refused before validating them (30 000 blocks cost ~ 10 s and 300 MB of
    validation only to be refused by dem.validate's size check after)."""
    path = Path(path)
    data, node = read_case_yaml(path)
    if max_blocks is None:
        from dem.environment import max_blocks_default

        max_blocks = max_blocks_default()
    n_listed = explicit_block_count(data)
    if n_listed > max_blocks:
        raise CaseError(
            f"{path}:{key_line(node, 'scene')}: scene.blocks: {n_listed:,} blocks listed, above "
            f"the limit of {max_blocks:,} blocks; not read further.  Raise the limit with "
            f"--max-blocks or DEM_MAX_BLOCKS if this is meant")
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
