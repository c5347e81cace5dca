"""The as-built study's grid experiments: case variants x frequencies x seeds of one first-
prediction sweep, run and judged by the diagnosis' grid machinery (studies.diagnosis.grid: the
case is the first prediction's sweep case with its frozen joints, patched by the variant; each
run judged by postprocess.verdicts.response_branch and postprocess.survival), recorded under
results/as-built/ instead of results/diagnosis/.
"""

from __future__ import annotations

from studies.diagnosis.grid import Grid, Variant
from studies.kit import study as kit

RESULTS = kit.results_dir("as-built")
RUNS = kit.runs_dir("as-built")

SEEDS = (0, 1, 2)
CYCLES = 10.0   # from rest, as E4's and E1's runs: comparable with their onsets


def as_built_grid(**fields) -> Grid:
    """A diagnosis grid whose records live under results/as-built/<key> (runs/as-built/<key>)."""
    return Grid(results_dir=RESULTS, runs_dir=RUNS, study="as-built", **fields)


UNBONDED = Variant("unbonded", "unbonded corners: straight vertical joints, no interlock",
                   {"scene": {"box_model": {"corners": "unbonded"}}})

# The corner bound (written before its runs, studies/as_built/__init__.py): the thesis' Model II
# y band at 1.53 m/s2 is quiet at 1.8-2.0 Hz, rocking at 2.4-3.2 Hz and quiet at 3.6 Hz (Table
# 4.9, lines 1017-1045); Model III y at 1.23 m/s2 rocks at 2.4-2.5 Hz (line 1143).
CORNER_BOUND_II_Y = as_built_grid(
    key="corner-bound-model-ii-y",
    title="Model II y with unbonded corners at 1.53 m/s2, 2.0-3.6 Hz, from rest",
    hypothesis="the interlocked corners hold the quiet branch stiff: without them Model II y "
               "rocks inside 2.4-3.2 Hz and stays quiet at 2.0 Hz",
    sweep="model-ii-y", variants=(UNBONDED,), frequencies=(2.0, 2.4, 2.8, 3.2, 3.6),
    seeds=SEEDS, cycles=CYCLES)
CORNER_BOUND_III_Y = as_built_grid(
    key="corner-bound-model-iii-y",
    title="Model III y with unbonded corners at 1.23 m/s2, 2.0-2.8 Hz, from rest",
    hypothesis="the interlocked corners hold Model III y quiet at the thesis' level",
    sweep="model-iii-y", variants=(UNBONDED,), frequencies=(2.0, 2.4, 2.8),
    seeds=SEEDS, cycles=CYCLES)

GRIDS = {g.key: g for g in (CORNER_BOUND_II_Y, CORNER_BOUND_III_Y)}
