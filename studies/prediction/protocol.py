"""The prediction's fixed choices: the sweeps and their order, the thesis numbers it is judged
against (../shared/REFERENCE.md, Chapter 4), the criteria's tolerances and the rules of the
cycles check.  The protocol itself: studies/prediction/__init__.py.
"""

from __future__ import annotations

from studies.kit.provenance import ROOT

DEFAULT_FROZEN = ROOT / "studies" / "calibration" / "frozen.yaml"
DEFAULT_CYCLES = 50          # thesis: 50 cycles per test (REFERENCE.md, Excitation)
DEFAULT_REALISATIONS = 10    # protocol step 3: at least 10 realisations per frequency
PARAM_KEYS = ("bed_unevenness", "face_shape", "size_scatter", "arris")
PROVENANCE_KEYS = ("derived_in", "candidate", "note", "frozen_on")
#: the order of the study: Model II y in full first (protocol step 3)
ORDER = ("model-ii-y", "model-ii-x", "model-ii-xy", "model-i-y", "model-i-x", "model-iii-y")
EXCITATION_CHECK = ("excitation as in the thesis (Appendix I peak accelerations, 50 cycles, or "
                    "fewer where shown not to change the answer)")
FULL_SWEEP = ORDER[0]        # run in full; its cycles check is what may justify a cut elsewhere
CHAPTER3_CHECK = "chapter3-check/check.json"  # under --out: studies.chapter3.check's record
MEASURED_FRICTION = 0.81     # small bricks, thesis Tables 3.1-3.2 (REFERENCE.md, Bricks)
SURVIVAL_MIN = 0.8           # protocol step 4: at least 80 % of the realisations survive
FC_TOL_HZ = 0.3              # characteristic frequency within +-0.3 Hz
AMP_FACTOR = 1.5             # amplification inside the range within x 1.5
AMP_RATIO_MIN = 3.0          # inside / outside > 3 for Model II
LAG_TOL_S = 0.05             # lag inside the range within +-0.05 s
EXCITED_REL_TOL = 0.2        # excited bricks within +-20 %
COURSES_TOL = 1              # excited courses within +-1
#: the amplifications a row keeps (postprocess.shake_signals: a_lp, a_front_lp the assumed
#: instrument low-pass; a_front, da_front the front facade's centre accelerometer)
ROW_QUANTITIES = ("ds", "dsr", "da", "a", "a_lp", "a_front", "a_front_lp", "da_front")
#: front / back amplification ratios: (front, back) quantities; da first (the headline: the
#: accelerometer-derived displacement, free of impact spikes and of the assumed cutoff)
FRONT_BACK = {"da": ("da_front", "da"), "a_lp": ("a_front_lp", "a_lp")}
CYCLES_REL_FLOOR = 0.1   # cycles check: medians agree within max(band width, 10 % of median)
TRUNCATED_CYCLES = (10, 20, 25, 30)   # cycles analyses kept as the points finish
LEFT_OUT = "left out"    # cycles check: a finished row whose raw run is not on this machine
NO_RAW_RUN = "no raw run on this machine: left out of both sides of the cycles check"
CYCLES_RULE = (
    "the answer at N cycles is unchanged from the full cycles when (1) the characteristic "
    "frequency is the same within one frequency step (both null, or at most one position apart "
    "in the sweep's sorted frequencies), (2) the medians of the ds amplification inside and "
    "outside the thesis' range agree within max(10-90 % band width at the full cycles, "
    f"{CYCLES_REL_FLOOR:g} x its median), and (3) the survival verdict (lowest survival rate "
    f">= {SURVIVAL_MIN:g}) is the same; the same runs, their first N cycles analysed as an "
    "N-cycle run (no new simulation)")

#: thesis numbers per sweep (../shared/REFERENCE.md, Chapter 4; protocol step 4).  peak_acc:
#: Appendix I constant peak accelerations (m/s2; the diagonal: 1.08 per axis); fc (Hz); range
#: [lo, hi] Hz (None: the text gives none); amp_in / amp_out: ds amplification inside / outside;
#: lag_in / lag_out (s); excited bricks and courses from the top.  Model I x: the thesis says only
#: "narrower" for its range, so "inside the thesis range" is its characteristic frequency alone;
#: the diagonal: no characteristic frequency in 1.7-3.6 Hz (the response grows up to 3.6 Hz).
THESIS = {
    "model-i-y": {"peak_acc": 1.53, "fc": 2.0, "range": [1.8, 2.5], "lag_in": 0.18,
                  "lag_out": 0.02, "courses": 8},
    "model-i-x": {"peak_acc": 1.71, "fc": 1.9, "range": None, "lag_in": 0.08, "lag_out": 0.06,
                  "courses": 6},
    "model-ii-y": {"peak_acc": 1.53, "fc": 2.8, "range": [2.4, 3.2], "amp_in": 2.0,
                   "amp_out_max": 0.5, "lag_in": 0.13, "lag_out": 0.03, "excited": 46,
                   "courses": 8, "a_in": 2.0, "front_back": 0.359},
    "model-ii-x": {"peak_acc": 1.71, "fc": 2.8, "range": [2.4, 2.8], "lag_in": 0.13,
                   "lag_out": 0.06, "excited": 50, "courses": 7, "front_back": 0.618},
    "model-ii-xy": {"peak_acc": 1.08, "fc": None, "fc_note": "> 3.6 Hz: the response grows up to "
                    "3.6 Hz, the highest frequency tested", "range": None},
    "model-iii-y": {"peak_acc": 1.23, "fc": 2.4, "range": [2.4, 2.5], "amp_in": 3.5,
                    "amp_out": 2.0, "excited": 62, "courses": 11, "front_back": 0.587},
}
#: a_in: the thesis' acceleration amplification inside the range (Model II y: "~2.0 (ds, a, vs)"),
#: context for a_lp, not a criterion.  front_back: the mean front / back amplification ratio of
#: Tables 4.9 - 4.11 (Section 4.3.4: "constant in each table", i.e. over frequency), context, not
#: a criterion; the front facade carried only an accelerometer (A5, Section 4.2.5), so these are
#: accelerometer amplifications (a or da: the thesis does not say which).


class PredictionInputError(ValueError):
    """Bad input (exit 2): the message names the file or option and the problem."""


