"""Impact dissipation of the DEM's rocking bodies against Housner and the two-body model: whether
the DEM's impacts lose what a rigid block's do, and whether it matters for the prediction.

    python -m studies impact-dissipation --out results/prediction/impact-dissipation

Runs (a) free rocking of single blocks, (b) the Model II y excited portion built of bricks,
(c) the two-body model (dem.rocking) with Housner's impact law and with the DEM's measured
restitution, (d) the dependence on the contact damping ratio (``--parts`` picks some; the others
keep their entries of an existing summary.json), and writes summary.json and
impact-dissipation.png under ``--out``; ``--tables`` prints the README's tables from it.  No run
directories or frames: the rotation histories go to /tmp/impact_dissipation_histories.npz only.

Closed forms (units SI: m, kg, s, rad; energies J)
-------------------------------------------------
Rigid body rocking on a rigid base about a bottom edge (planar).  Seen from the pivot O about
which it rocks, its centre of mass G lies at a horizontal distance c (towards the body) and a
height z.  Tilted by theta (>= 0, G moving towards the vertical over O) its rocking energy is

    E(theta) = M g (z cos theta + c sin theta - z)                                  [J]

(= M g R (cos(alpha - theta) - cos alpha) for a uniform block, R = |OG|, tan alpha = c / z).
Released at rest from theta0 it returns to theta = 0 with kinetic energy E(theta0); the next
excursion (about the other edge, distance c', height z) reaches theta1 with E'(theta1) = r^2
E(theta0), r = omega+ / omega- the impact's restitution (ratio of angular velocities).

Housner (1963) for a plastic impact on the new edge O', a distance b from O: angular momentum
about O' is conserved, I_G omega- + M (G - O') x v_G- = I_O' omega+, so

    r = (I_O - M b c) / I_O',   I_O = I_G + M (c^2 + z^2),  I_O' = I_G + M ((b - c)^2 + z^2)

which for a uniform rectangle (c = b/2, I_O = I_O' = M (b^2 + h^2) / 3) is

    r = 1 - M b^2 / (2 I_O) = 1 - 1.5 sin^2 alpha,   tan alpha = b / h,

and the energy kept per impact is r^2.  At small amplitudes E is nearly linear in theta
(E ~ M g c theta), so the amplitude ratio of successive half cycles is ~ r^2 (8.5 % lost per
impact for r = 0.957); the exact amplitude map is :func:`amplitude_after_impact`.

What is measured
----------------
From a rotation history theta(t) (rad) the half-cycle peaks are the extremes of |theta| between
impacts (:func:`half_cycle_peaks`: local maxima of |theta| separated by returns close to 0).  Per
impact k -> k+1: the amplitude ratio A_{k+1} / A_k and the energy ratio E(A_{k+1}) / E(A_k) with
each lobe's own pivot (c, z), whose square root is the equivalent restitution r_eq
(:func:`impact_ratios`).  For single blocks also the angular velocity just before and after each
impact (:func:`omega_ratios`), read at |theta| = d and carried to theta = 0 with the rigid-body
energy equation, omega(0)^2 = omega(d)^2 + 2 E(d) / I_O.

The two-body model (dem.rocking) is run with its own impact map: ``restitution: housner`` (the
plastic Moreau / Housner impact of the two parts) or a number e, which keeps the plastic velocity
direction and e^2 of the kinetic energy, so e = r_eq transfers the DEM's measured energy loss per
impact to it (dem/rocking/impacts.py).

DEM settings: the shake cases' material (friction 0.81, base_friction 1.5) and the defaults of
dem.case.Material / SolverSpec (kn = 5e9 Pa/m, ks = 0.4 kn, damping 0.5 of critical, dt = 0.3 of
critical); only part (d) changes the damping ratio.

The pieces, by job: physics.py (closed forms, measuring on a history), dem_runs.py, two_body.py
(the runs), report.py (summary, plot, tables), cli.py.
"""
