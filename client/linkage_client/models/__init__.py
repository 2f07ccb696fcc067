"""Typed models of the service's answers (frozen dataclasses, numpy arrays for the numbers).

Why dataclasses and not pydantic: the client needs nothing but httpx and numpy, its fields hold
numpy arrays (which pydantic validates only as arbitrary types), and validation is the
service's job (the contract lets it add fields: unknown keys are ignored here, and every model
of an answer keeps the whole JSON on ``raw``). Field names are the answer's keys (``from`` is
``from_``); ``tests/client/test_models.py`` checks them against ``openapi/openapi.json``.

``linkage`` holds the linkage and the small answers, ``analysis`` the answers of the analysis
and design operations, ``jobs`` the jobs, the sweeps and the result model of each operation.
"""

from linkage_client.models.analysis import (
    BranchSplit,
    CellSigns,
    Component,
    ConeSplit,
    Conflict,
    CriticalPoint,
    CriticalPointsResult,
    CriticalValuesResult,
    DesignResult,
    DualCertificate,
    HeightCritical,
    NearMiss,
    Predicted,
    Region,
    RigidityResult,
    RobustnessResult,
    RobustnessSearch,
    SecondOrderFlex,
    SecondOrderResult,
    Segment,
    SliceSearch,
    SpaceResult,
    SplittingResult,
    StressCertificate,
    Surface,
    SurfaceDesign,
    SurfaceSplit,
)
from linkage_client.models.jobs import (
    FINISHED,
    RESULTS,
    Job,
    JobError,
    JobSummary,
    Operation,
    Progress,
    SweepResult,
    SweepRow,
    SweepSummary,
    result_of,
)
from linkage_client.models.linkage import (
    Bar,
    CountClaim,
    Health,
    Linkage,
    PresetInfo,
    ProvedSoFar,
    Readiness,
    SearchReport,
    TangentForm,
    TolerancesUsed,
    Vertex,
    linkage_json,
    sequence,
)

__all__ = [
    "FINISHED", "RESULTS", "Bar", "BranchSplit", "CellSigns", "Component", "ConeSplit", "Conflict",
    "CountClaim", "CriticalPoint", "CriticalPointsResult", "CriticalValuesResult", "DesignResult",
    "DualCertificate", "Health", "HeightCritical",
    "Job", "JobError", "JobSummary", "Linkage", "NearMiss", "Operation", "PresetInfo", "Predicted",
    "ProvedSoFar",
    "Progress", "Readiness", "Region", "RigidityResult", "RobustnessResult", "RobustnessSearch",
    "SearchReport", "SecondOrderFlex", "SecondOrderResult", "Segment", "SliceSearch",
    "SpaceResult", "SplittingResult", "StressCertificate", "Surface", "SurfaceDesign",
    "SurfaceSplit",
    "SweepResult", "SweepRow",
    "SweepSummary", "TangentForm", "TolerancesUsed", "Vertex", "linkage_json", "result_of",
    "sequence",
]
