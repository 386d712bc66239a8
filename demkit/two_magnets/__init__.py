"""The seed paper's two-body study (Bartz & Shaw): two magnets colliding off-centre.

* :class:`TwoMagnets` -- the paper's collision ready-made (:mod:`.scene`);
* :mod:`.analysis` -- final spin, final state and outcome (miss / bounce / stick) of a colliding pair;
* :mod:`.capture` -- capture-threshold search; :mod:`.fits` -- fits of beta and energy ratios.

The core of demkit (:mod:`demkit.scene`, :mod:`demkit.simulation`, ...) knows nothing of this study.
"""
from . import analysis, capture, fits
from .analysis import FinalState, UndeterminedOutcome, final_spin, final_state, outcome
from .scene import (BARBELL_BETA, PAPER_DAMPING, PAPER_PREFACTOR, PAPER_RADIUS, PAPER_SPEED,
                    POINT_MASS_BETA, TwoMagnets)

__all__ = ["TwoMagnets", "analysis", "capture", "fits", "final_spin", "final_state", "outcome",
           "FinalState", "UndeterminedOutcome", "PAPER_RADIUS", "PAPER_SPEED", "PAPER_DAMPING",
           "PAPER_PREFACTOR", "BARBELL_BETA", "POINT_MASS_BETA"]
