"""The local floor: analysis at one configuration. First order (rank, zero modes, self-stresses,
tangent form: :mod:`.rigidity`), second order and its shape (:mod:`.second_order`), prestress
stability with certificates (:mod:`.prestress`), critical points refined and classified
(:mod:`.critical`, :mod:`.critical_batched` from many starts at once).
"""

from engine.local.critical import CriticalPoint, NearMiss, Refined, classify, refine_critical
from engine.local.prestress import PrestressResult, prestress
from engine.local.rigidity import RigidityResult, TangentForm, first_order
from engine.local.second_order import SecondOrderResult, second_order

__all__ = [
    "CriticalPoint",
    "NearMiss",
    "PrestressResult",
    "Refined",
    "RigidityResult",
    "SecondOrderResult",
    "TangentForm",
    "classify",
    "first_order",
    "prestress",
    "refine_critical",
    "second_order",
]
