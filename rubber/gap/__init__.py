"""Sim-to-real gap diagnosis for the PRF model (issue 7, point 6): which unmodelled effect explains
where a calibrated PRF model misses a held-out protocol.

The model family is a :class:`rrfrei.gap.GapModel` (:class:`RubberModel`): PRF fits are optimizer
fits (CMA-ES from :mod:`rubber.fit`, then bounded least squares) with importance-corrected Laplace
draws, so the one gap engine, :func:`rrfrei.gap.diagnose`, diagnoses rubber as it diagnoses isolators
and buildings (block rule over loading cycles, held-out shrink with its interval; the candidates are
this catalogue's, :attr:`RubberModel.candidate_effects`).  :func:`rank_effects` is the optimiser-only
ranking of ``python -m rubber gap``: an information criterion on the calibration data and the error
on held-out protocols, for protocols too short for the block rule.

Effect catalogue (:data:`EFFECTS`), both acting on the equilibrium (Yeoh) network only; the viscous
Bergstrom-Boyce chains see the total stretch as before, so the effects post-process the equilibrium
row of the PRF simulation and the augmented model is exactly the base model at neutral values.

``mullins`` (parameters ``d_mullins`` = 1/r, ``beta_mullins``): Ogden-Roxburgh damage
    Delta_A = eta Delta_A0,   eta = 1 - d erf((W_max - W) / (beta W_max)),
    W the Yeoh energy of the current (elastic) stretch, W_max its maximum over the history.
    Ogden & Roxburgh (1999), Proc. R. Soc. A 455:2861, eq. (5.4); the m = 0 member of the
    ``m + beta W_max`` denominator of Abaqus' *MULLINS EFFECT.  Reloading below the previous maximum is
    softer than virgin loading (eta < 1) and rejoins it at W = W_max.  Neutral: d = 0.
``permanent_set`` (parameter ``s_set``): the equilibrium network's reference stretch moves with the
    largest stretch reached, F = F_e F_p, lambda_p = 1 + s (lambda_max - 1), lambda_max = max(1, max
    lambda), and Delta_A = Delta_Yeoh(lambda / lambda_p).  The set grows with the maximum stretch, as
    observed for filled rubbers (Dorfmann & Ogden 2004, Int. J. Solids Struct. 41:1855; review by
    Diani, Fayolle & Gilormini 2009, Eur. Polym. J. 45:601); the linear law is our choice, the
    simplest with that property.  Neutral: s = 0.

Units: MPa, s; nominal stress P = (Delta_A + sum_k Delta_k) / lambda.

Modules: :mod:`rubber.gap.kernels` (Numba), :mod:`rubber.gap.effects` (the catalogue and
:func:`augmented_stress`), :mod:`rubber.gap.model` (:class:`RubberModel`, :class:`RubberFit`) and
:mod:`rubber.gap.ranking` (:func:`rank_effects`, :class:`RubberGapReport`).

Layer: on the ``rrfrei`` core's gap engine (``rrfrei.gap``); beside ``structures``, below
``rrfrei.app``.
"""

# the kernels and constants stay reachable as rubber.gap.<name>, as when this was one module
from rubber.gap.effects import EFFECT_PARAMS, EFFECTS, Effect, augmented_stress  # noqa: F401
from rubber.gap.kernels import augmented_nominal, equilibrium_delta, mullins_factor, set_reference  # noqa: F401
from rubber.gap.model import LSQ_EVALS_PER_DIM2, Z_BAND, RubberFit, RubberModel  # noqa: F401
from rubber.gap.ranking import CRITERION, MARGIN, EffectRow, RubberGapReport, rank_effects

__all__ = ["Effect", "EFFECTS", "CRITERION", "MARGIN", "augmented_stress", "RubberModel", "RubberFit",
           "EffectRow", "RubberGapReport", "rank_effects"]
