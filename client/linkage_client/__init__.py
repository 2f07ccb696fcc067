"""Python client of the linkage topology service: sync and async, typed answers, numpy arrays.

>>> from linkage_client import Client                          # doctest: +SKIP
>>> with Client("http://127.0.0.1:8000") as c:                 # doctest: +SKIP
...     space = c.explore_configuration_space(c.get_preset_four_bar())
...     space.components[0].positions.array.shape              # (n, V, d)

It talks HTTP only (httpx): nothing of the service's code is imported. Conversions to and from
PyRigi, networkx, pylinkage and FOLD are in ``linkage_client.formats``.
"""

from linkage_client._http import RetryPolicy
from linkage_client.aio import AsyncClient
from linkage_client.errors import (
    ClientError,
    JobCancelled,
    JobFailed,
    JobTimeout,
    ProblemError,
    ProblemItem,
)
from linkage_client.labelled import Labelled, decode_packed
from linkage_client.models import (
    Bar,
    Component,
    CriticalPoint,
    CriticalPointsResult,
    CriticalValuesResult,
    DesignResult,
    Health,
    Job,
    Linkage,
    Operation,
    PresetInfo,
    RigidityResult,
    RobustnessResult,
    SecondOrderResult,
    SpaceResult,
    SplittingResult,
    SweepResult,
    Vertex,
)
from linkage_client.progress import TextBar
from linkage_client.sync import Client

__version__ = "0.1.0"

__all__ = [
    "AsyncClient", "Bar", "Client", "ClientError", "Component", "CriticalPoint",
    "CriticalPointsResult", "CriticalValuesResult", "DesignResult", "Health", "Job",
    "JobCancelled", "JobFailed", "JobTimeout", "Labelled", "Linkage", "Operation", "PresetInfo",
    "ProblemError", "ProblemItem", "RetryPolicy", "RigidityResult", "RobustnessResult",
    "SecondOrderResult", "SpaceResult", "SplittingResult", "SweepResult", "TextBar", "Vertex",
    "decode_packed", "__version__",
]
