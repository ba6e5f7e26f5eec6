"""Sim-to-real gap diagnosis (issue 7): where a calibrated law misses, which unmodelled effect
closes the gap, and how far.

Layers: effect kernels (:mod:`rrfrei.laws.effects`) -> catalogue metadata and signature screens
(:mod:`.catalogue`) -> generic model interface and the isolator implementation (:mod:`.model`)
-> residual segmentation (:mod:`.residuals`) -> engine (:mod:`.diagnose`) -> validation on
withheld effects (:mod:`.validate`) and the Markdown report (:mod:`.report`).

>>> import rrfrei
>>> rep = rrfrei.diagnose_gap("protocol1", "plasticity", holdout=["protocol2"])  # doctest: +SKIP
>>> rep.diagnosis  # doctest: +SKIP
"""

from rrfrei.gap.diagnose import CONFOUNDED, EffectScore, GapReport, Metrics, diagnose, diagnose_gap
from rrfrei.gap.isolator import IsolatorFit, IsolatorModel
from rrfrei.gap.model import FitResult, GapModel, Prediction

__all__ = ["CONFOUNDED", "EffectScore", "FitResult", "GapModel", "GapReport", "IsolatorFit",
           "IsolatorModel", "Metrics", "Prediction", "diagnose", "diagnose_gap"]
