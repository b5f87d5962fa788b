"""Edit propagation (Ikemoto, Arikan & Forsyth 2009, ``../shared/seeds/002_…``).

An animator edits a few seconds of a source clip; two Gaussian processes learn the
edit — one predicts each frame's target configuration, one its acceleration, each with
a variance — and a banded linear solve per output combines them, regularised toward the
source where the predictions are unsure, to edit minutes of other motion.

- :mod:`rigmap.edits.gp`: the GP predictor (RBF + noise, three hyper-parameters shared
  by all outputs, marginal-likelihood fit, predictive variance);
- :mod:`rigmap.edits.combine`: the combined solve of Eqs 7–12 as one banded SPD system;
- :mod:`rigmap.edits.features`: source features (§4.5): the skeleton around each frame in
  its own heading frame, and smoothed root-relative accelerations;
- :mod:`rigmap.edits.mirror`: training data mirrored left/right (§7.1), per rig;
- :mod:`rigmap.edits.mls`: moving least squares (§4.4) behind the GP's interface;
- :mod:`rigmap.edits.authoring`: edit authoring (§5) — the bone-length IK (Newton on the
  Lagrangian, pins), minimal-rotation angles, offset and timing signals blended in and out;
- :mod:`rigmap.edits.incremental`: incremental refinement (§3, Fig 2) — fixed frames join
  the examples, refit, the highest-variance frames suggested next.
"""
