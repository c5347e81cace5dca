"""Impact loss of a free-rocking block against Housner, by slenderness, for the normal dashpots
of the joint (material.normal_damping: critical, pair, stiffness; docs/engine.md section 6).

    python -m studies impact-loss --out results/impact-loss

A uniform block of width b = 0.1 m (depth 0.1 m, density 2000 kg/m3, the rocking-block case's
block) and height h = (h/b) b, on the table with the default joint (kn = 5e9 Pa/m, ks = 0.4 kn,
friction 0.8, so that it rocks without sliding), is released at rest leaning on its +x bottom
edge by half its slenderness angle alpha = atan(b/h) and rocks freely under gravity.  Measured
(studies.impact_dissipation.physics, the method of tests/test_engine_physics.py): at each of the
first impacts the angular velocity just before and after, read where |theta| = 5 % of the release
angle and carried to theta = 0 with the rigid block's energy equation,

    r = omega+ / omega-,   omega(0)^2 = omega(d)^2 + 2 E(d) / I_O,

and its ratio to Housner's (1963) plastic impact of the rigid block, r_H = 1 - 1.5 sin^2 alpha.
The first impact's r / r_H is the table's number (later impacts at smaller amplitudes are
listed in summary.json).  Target: ElGawady, Ma, Butterworth & Ingham (2011, Earthquake Eng.
Struct. Dyn. 40:375; the same tests in their conference chapter "Effects of interface material on
the dynamic behaviour of rigid blocks"): blocks of aspect ratio 3 and 5 rocking on a concrete
base kept r of about 0.97 and 0.95 of Housner's.

The pieces: runs.py (the laws, one block's run and its measurement), cli.py (the slenderness
sweep for each law and the size check at h/b = 4, summary.json, the plot and the table).
"""
