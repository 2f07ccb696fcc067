"""Conversions shared by every resource: linkages and tolerances in, vectors and linkages out."""

from __future__ import annotations

import numpy as np
import pybase64

from engine.model.linkage import Limits, build_linkage
from engine.model.linkage import Linkage as EngineLinkage
from engine.model.tolerances import Tolerances as EngineTolerances
from engine.model.tolerances import check_residual_scale, check_resolution, scaled_tolerances
from engine.model.vectors import normalised
from service.gcpause import gc_paused
from service.schemas import common as c
from service.schemas import space

#: The largest integer a JSON number holds exactly everywhere (a double's 53-bit significand,
#: JavaScript's ``Number.MAX_SAFE_INTEGER``): counts beyond it (a Kane-Lubensky chain of n
#: spinners has 2^(n-1) components) are answered as decimal strings.
MAX_JSON_INT = 2**53 - 1


def json_int(value: int) -> int | str:
    """``value`` as a JSON number when it is exact in a double, else as its decimal string
    (which no JSON encoder refuses and no client rounds)."""
    return value if -MAX_JSON_INT <= value <= MAX_JSON_INT else decimal_digits(value)


#: Digits per piece of :func:`decimal_digits` (below Python's 4300-digit limit on ``str(int)``).
PIECE_DIGITS = 1000


def decimal_digits(value: int) -> str:
    """The decimal string of an integer of any size: ``str`` refuses integers of more than
    4300 digits (the 20000-rotor chain has 2^19999 components, 6021 digits: a 500), so the
    digits are taken a thousand at a time (``divmod`` has no such limit)."""
    sign, value = ("-" if value < 0 else ""), abs(value)
    base = 10**PIECE_DIGITS
    pieces: list[str] = []
    while value >= base:
        value, low = divmod(value, base)
        pieces.append(str(low).zfill(PIECE_DIGITS))
    return sign + str(value) + "".join(reversed(pieces))


#: Default margin of ``/v1/design/splitting``, relative to the median bar length.


#: Default margin of ``/v1/design/splitting``, relative to the median bar length.
DEFAULT_MARGIN = 1e-4


def linkage_in(model: c.Linkage, limits: Limits) -> EngineLinkage:
    """Request linkage -> validated engine linkage (raises EngineError with field locations)."""
    # The request models have the fields of VertexSpec and BarSpec: passed as they are, since
    # copying 20,000 of them into dataclasses costs more than the whole check.
    with gc_paused():
        return build_linkage(model.dimension, model.vertices, model.bars, limits)


def problem_in(
    linkage: c.Linkage, tolerances: c.Tolerances | None, limits: Limits
) -> tuple[EngineLinkage, EngineTolerances]:
    """Request linkage and tolerances -> validated engine linkage and the tolerances to use:
    those given, else the defaults, with ``residual_atol`` scaled to the linkage's median bar
    length. Positions that float64 cannot resolve to that tolerance are refused."""
    engine_linkage = linkage_in(linkage, limits)
    given = tolerances.model_dump(exclude_none=True) if tolerances else {}
    lengths = engine_linkage.lengths
    scale = float(np.median(lengths)) if lengths.size else 1.0
    tol = scaled_tolerances(scale, **given)
    check_residual_scale(tol, scale)
    check_resolution(engine_linkage.positions, tol)
    return engine_linkage, tol


def tolerances_out(tol: EngineTolerances) -> c.TolerancesUsed:
    return c.TolerancesUsed(
        rank_rtol=tol.rank_rtol, residual_atol=tol.residual_atol, q_rtol=tol.q_rtol
    )


def _fixed_out(mask: np.ndarray) -> bool | list[bool]:
    if mask.all():
        return True
    if not mask.any():
        return False
    return [bool(b) for b in mask]


def linkage_out(linkage: EngineLinkage) -> c.Linkage:
    """Engine linkage -> response linkage (lengths always explicit)."""
    return c.Linkage(
        dimension=linkage.dimension,  # type: ignore[arg-type]
        vertices=[
            c.Vertex(id=vid, position=pos.tolist(), fixed=_fixed_out(mask))
            for vid, pos, mask in zip(
                linkage.vertex_ids, linkage.positions, linkage.fixed, strict=True
            )
        ],
        bars=[
            c.Bar(id=bid, ends=[linkage.vertex_ids[i], linkage.vertex_ids[j]], length=float(ln))
            for bid, (i, j), ln in zip(linkage.bar_ids, linkage.ends, linkage.lengths, strict=True)
        ],
    )


def vertex_vectors(linkage: EngineLinkage, v: np.ndarray) -> c.VertexVectors:
    """Free-coordinate vector (M,) -> normalised ``{vertex_id: [..]}`` (fixed axes 0)."""
    lifted = linkage.vertex_vectors(normalised(v))
    return dict(zip(linkage.vertex_ids, lifted.tolist(), strict=True))


def positions_out(linkage: EngineLinkage, positions: np.ndarray) -> c.VertexVectors:
    return dict(zip(linkage.vertex_ids, positions.tolist(), strict=True))


def bar_values(linkage: EngineLinkage, v: np.ndarray) -> c.BarValues:
    """Per-bar vector (E,) -> normalised ``{bar_id: value}``."""
    return dict(zip(linkage.bar_ids, normalised(v).tolist(), strict=True))


def _raw_vertex_vectors(linkage: EngineLinkage, v: np.ndarray) -> c.VertexVectors:
    """As :func:`vertex_vectors` without renormalising: certificates are written in this exact
    basis and scale (a sign flip would change the dual matrix or the sign of the energy)."""
    return dict(zip(linkage.vertex_ids, linkage.vertex_vectors(v).tolist(), strict=True))


def packed_array(ids: list[str], values: np.ndarray) -> space.PackedArray:
    """``values`` (n, len(ids), ...) as a PackedArray: little-endian float64, C order, base64
    (pybase64's SIMD encoder, straight to a str: some 2 ms for 10 MB, the standard library's
    ``base64.b64encode(...).decode()`` some 25 ms)."""
    data = np.ascontiguousarray(values, dtype="<f8")
    return space.PackedArray.model_construct(
        ids=list(ids), shape=list(data.shape), dtype="<f8",
        base64=pybase64.b64encode_as_string(data.data))
