"""``run:`` (what is recorded, how long) and ``solver:`` (numerical knobs) of a case file."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from dem.case.base import StrictModel


class RunSpec(StrictModel):
    """How long to run and what to write (frames.npz always holds every output frame)."""

    duration: float = Field(gt=0.0, description="simulated time, s")
    output_interval: float = Field(default=0.01, gt=0.0, description="time between frames, s")
    vtk: bool = Field(default=True, description="write vtk/ (one .vtu per written frame)")
    vtk_every: int = Field(
        default=1, ge=1, description="write a .vtu for every k-th output frame"
    )
    contacts: bool = Field(
        default=False, description="also write contact points and forces (vtk/contacts_*.vtp)"
    )
    snapshot: bool = Field(default=True, description="write final.png (off-screen rendering)")
    instruments: Literal["auto", "none", "thesis"] = Field(
        default="auto",
        description="virtual instruments (instruments.npz): 'thesis' = Fig 4.4 on a box model; "
        "'auto' = thesis for a shaken box model, none otherwise",
    )
    instrument_interval: float = Field(
        default=0.002, gt=0.0, description="s between instrument samples (500 Hz)"
    )


class SolverSpec(StrictModel):
    """Numerical knobs.  Every default is justified by a measurement in benchmarks/RESULTS.md."""

    dt: float | None = Field(default=None, gt=0.0, description="time step, s (default: automatic)")
    safety: float = Field(
        default=0.3, gt=0.0, le=1.0,
        description="automatic dt = safety * critical dt (0.3: results equal to a 6x smaller "
        "step; 0.6 breaks down, benchmarks/speed_error.md)",
    )
    skin: float | None = Field(
        default=None, gt=0.0, description="neighbour-list skin, m (default 0.05 * smallest block edge)"
    )
    max_pairs_per_block: int = Field(
        default=16, ge=2, description="neighbour-list capacity per block (overflow stops the run)"
    )
    overlap_tolerance: float = Field(
        default=1e-4, gt=0.0, description="largest initial overlap accepted, m"
    )
    max_speed: float = Field(
        default=50.0, gt=0.0, description="a block faster than this stops the run (runaway), m/s"
    )
    local_damping: float = Field(
        default=0.0, ge=0.0, lt=1.0, description="Cundall local (non-viscous) damping, -"
    )
    mode: Literal["auto", "serial", "parallel"] = Field(
        default="auto", description="serial multi-step kernel or one parallel kernel per step"
    )
    threads: int | None = Field(default=None, ge=1, description="CPU threads (default: all)")
    precision: Literal["f64", "f32"] = Field(
        default="f64",
        description="floating point of the engine (f32 only for speed/error studies: one "
        "precision per process)",
    )
    patch_reuse: float = Field(
        default=1e-7, ge=0.0, le=1e-3,
        description="reuse a closed joint's contact patch while its faces drift less than this "
        "in their plane, m (0 = off: a full narrow phase every step; dem/engine/coherence.py). "
        "1e-7: results within the round-off sensitivity of the thesis' cases, 1.1-1.3x faster "
        "(benchmarks/speed_error.md)",
    )
    overlap_reuse: float = Field(
        default=0.0, ge=0.0, le=1e-3,
        description="keep an imperfect joint's overlap polygon while its corners drift less than "
        "this, m (0 = off, the default): the incident face's corners, in the reference face's "
        "plane; only the gap, its clip and the quadrature are redone each step "
        "(dem/engine/coherence.py set_overlap_reuse). No effect on a scene without imperfect "
        "faces (summary.json joints.overlap_reuse says so). 1e-7: 1.2-1.3x less CPU, imperfect "
        "Model II ds amplification within 0.3 % (benchmarks/RESULTS.md, 'Overlap reuse')",
    )
