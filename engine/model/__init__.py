"""The model floor: what a linkage is and the maps every analysis stands on.

Linkages (:mod:`.linkage`), the constraint map, its Jacobian and projection (:mod:`.constraints`,
:mod:`.hessian`, :mod:`.batched` for many configurations at once), one LU with the determinant's
sign (:mod:`.lu`), tolerances (:mod:`.tolerances`), errors (:mod:`.errors`), time budgets
(:mod:`.budget`), memory budgets (:mod:`.memory`), a search's report (:mod:`.report`) and the
vector convention (:mod:`.vectors`).
Imports nothing from the floors above.
"""

from engine.model.batched import BatchedConstraints, project_many
from engine.model.budget import Deadline
from engine.model.constraints import Constraints, ProjectionResult, on_constraints, project
from engine.model.errors import (
    EngineError,
    InvalidLinkage,
    InvalidParameter,
    InvalidRequest,
    InvalidTolerance,
    LimitExceeded,
    NoNearbySolution,
    NumericalFailure,
    UnknownPreset,
)
from engine.model.hessian import dense_stress_hessian
from engine.model.linkage import BarSpec, Limits, Linkage, VertexSpec, build_linkage
from engine.model.lu import BandLU, BorderedFactor, Factor
from engine.model.report import SearchReport
from engine.model.tolerances import Tolerances
from engine.model.vectors import normalise_sign, normalised

__all__ = [
    "BandLU",
    "BarSpec",
    "BatchedConstraints",
    "BorderedFactor",
    "Constraints",
    "Deadline",
    "EngineError",
    "Factor",
    "InvalidLinkage",
    "InvalidParameter",
    "InvalidRequest",
    "InvalidTolerance",
    "LimitExceeded",
    "Limits",
    "Linkage",
    "NoNearbySolution",
    "NumericalFailure",
    "ProjectionResult",
    "SearchReport",
    "Tolerances",
    "UnknownPreset",
    "VertexSpec",
    "build_linkage",
    "dense_stress_hessian",
    "normalise_sign",
    "normalised",
    "on_constraints",
    "project",
    "project_many",
]
