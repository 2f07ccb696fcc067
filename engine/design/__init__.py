"""The design floor: from configuration spaces to design decisions. How branch points split
(:mod:`.splitting`), lengths that program chosen splittings (:mod:`.design`), critical-value maps
(:mod:`.critical_values`), robustness margins (:mod:`.robustness`, exact for dyad chains in
:mod:`.dyad_margin`) and sweeps over families (:mod:`.sweep`).
"""

from engine.design.critical_values import Slice, critical_value_slice
from engine.design.design import DesignResult, Target, design, verify
from engine.design.robustness import Margin, robustness
from engine.design.splitting import Split, length_change, split
from engine.design.sweep import Family, PointResult, run_points, summarize

__all__ = [
    "DesignResult",
    "Family",
    "Margin",
    "PointResult",
    "Slice",
    "Split",
    "Target",
    "critical_value_slice",
    "design",
    "length_change",
    "robustness",
    "run_points",
    "split",
    "summarize",
    "verify",
]
