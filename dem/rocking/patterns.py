"""Contact modes of the two-body rocking model: pattern labels, equation sets, pivot geometry.

A mode is ``(b, c, tau, sigma)``, one entry per contact (no sliding, no flight - the thesis'
assumptions; conventions in :mod:`dem.rocking.params`):

* base contact ``b``: +1 = Part 1 rocks on its +x bottom corner (theta1 > 0), -1 on its -x corner,
  0 = Part 1 flat on the base (theta1 = omega1 = 0, the contact carries a moment);
* interface ``c``: +1 = Part 2 rocks on the +x top corner of Part 1 (phi > 0), -1, 0 = flat;
* top friction ``tau``: +1 / -1 = the load point of Part 2 slides towards +x / -x under the beam,
  friction F = -tau mu N; 0 = it sticks (|F| <= mu N, F from the constraint x_p' = 0);
* ``sigma`` = sign of theta2: which top corner of Part 2 is raised and carries the beam load N.

Patterns: (b, c) = (+,+) 1A, (-,-) 1B, (+,-) 2A, (-,+) 2B, (+,0) 3A, (-,0) 3B; not in the thesis:
(0,+) 4A / (0,-) 4B = Part 1 resting flat, Part 2 rocking on it; (0,0) "rest".

Which equations govern a mode (:func:`flow_kind`; the equations: :mod:`dem.rocking.equations`)
and which corners are the pivots (:func:`geometry`) follow from (b, c, tau) alone.  Which mode
holds at a state is decided in :mod:`dem.rocking.modes`.
"""

from __future__ import annotations

from dem.rocking.params import RockingParams

PATTERNS = ("rest", "1A", "1B", "2A", "2B", "3A", "3B", "4A", "4B")


def pattern_name(b: int, c: int) -> str:
    """Pattern label of the contact modes (b, c); see the module docstring."""
    if b == 0 and c == 0:
        return "rest"
    if c == 0:
        return "3A" if b > 0 else "3B"
    if b == 0:
        return "4A" if c > 0 else "4B"
    if b == c:
        return "1A" if b > 0 else "1B"
    return "2A" if b > 0 else "2B"


def flow_kind(b: int, c: int, tau: int) -> str:
    """Which set of equations governs the mode (b, c, tau)."""
    if b != 0 and c != 0:
        return "free" if tau else "free_stick"
    if b != 0:
        return "p3" if tau else "p3_stuck"
    if c != 0:
        return "p4" if tau else "p4_stuck"
    return "rest"


STATIONARY = ("rest", "p3_stuck", "p4_stuck")


def geometry(P: RockingParams, b: int, c: int) -> tuple[int, int]:
    """Pivot geometry (s1, s2) used for the mode (b, c); flat contacts use a reference side."""
    s1 = b if b != 0 else (c if c != 0 else 1)
    s2 = c if c != 0 else s1
    return s1, s2
