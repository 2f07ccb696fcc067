"""Sweeps: one analysis over a family of linkages (a grid of lengths, or Monte Carlo samples).

A *family* maps a point ``values`` (P,) of the swept names to one linkage: either the bars of a
given linkage with their lengths replaced (:class:`BarFamily`; the configuration space is then
searched from seeds, since the given positions no longer satisfy the lengths), or a preset built
with its parameters replaced (:class:`PresetFamily`; assembled on its configuration space, or
empty where the lengths assemble nowhere).

Each point is analysed on its own (:func:`evaluate`), so a sweep splits into chunks that run
anywhere (the service runs them on Dask); :func:`run_points` runs one chunk and reports
"points done" to a :class:`~engine.model.budget.Deadline`, which also stops it (time, cancellation).
:func:`summarize` condenses the rows.

What the points share is the chain's cell structure: where the chain rules count a point's
components (rotor chains, chains with the paper's gate), its row is derived from them
(:mod:`engine.design.sweep_rules`: the count, the rotor-turn pattern and ``gated``, in a
few milliseconds a point with the preset's build, no tracing); elsewhere the point is
explored. Either way a row is complete only with an argument, as a single exploration is, and
``gated`` never rests on which components happened to be traced (see :class:`PointResult`).

>>> fam = PresetFamily("four-bar", {}, ("L2",))
>>> pts = grid_points([GridAxis("L2", 0.5, 3.5, 4)])  # L2 = 0.5, 1.5, 2.5, 3.5
>>> [r.components for r in run_points(fam, pts, ("components",))]
[2, 1, 1, 0]
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.catalogue.presets import build_preset, resolve_parameters
from engine.design.region_labels import touched_cells
from engine.design.robustness import robustness
from engine.design.sweep_rules import DerivedRow, derive
from engine.model.budget import ARGUMENT_DERIVED, NEVER, Argument, Deadline
from engine.model.errors import EngineError, InvalidParameter, InvalidRequest, NumericalFailure
from engine.model.linkage import Linkage, changeable_bar
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import (
    SpaceOptions,
    SpaceResult,
    explore,
    find_critical_points,
    positions_along,
    rotor_angles,
    winding,
)
from engine.space.four_bar_cells import FourBarCell

#: What a sweep can compute at each point, in the order of the rows' columns.
COMPUTE = ("components", "critical", "margin", "windings")


@dataclass(frozen=True)
class GridAxis:
    """``steps`` evenly spaced values from ``lo`` to ``hi`` (both included)."""

    name: str
    lo: float
    hi: float
    steps: int


@dataclass(frozen=True)
class SampleAxis:
    """Normally distributed values (e.g. a length with a manufacturing tolerance ``sd``)."""

    name: str
    mean: float
    sd: float


def grid_points(axes: Sequence[GridAxis]) -> np.ndarray:
    """Every point of the grid (N, P), the last axis varying fastest.

    >>> grid_points([GridAxis("a", 0, 1, 2), GridAxis("b", 5, 6, 2)]).tolist()
    [[0.0, 5.0], [0.0, 6.0], [1.0, 5.0], [1.0, 6.0]]
    """
    ticks = [np.linspace(a.lo, a.hi, a.steps) for a in axes]
    mesh = np.meshgrid(*ticks, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def sample_points(axes: Sequence[SampleAxis], count: int, seed: int) -> np.ndarray:
    """``count`` Monte Carlo points (count, P), reproducible with ``seed``."""
    rng = np.random.default_rng(seed)
    mean = np.array([a.mean for a in axes], dtype=float)
    sd = np.array([a.sd for a in axes], dtype=float)
    return mean + sd * rng.standard_normal((count, len(axes)))


@dataclass(frozen=True)
class BarFamily:
    """``linkage`` with the lengths of ``bars`` (ids) replaced by a point's values."""

    linkage: Linkage
    names: tuple[str, ...]
    on_space: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        for k, bar in enumerate(self.names):
            changeable_bar(self.linkage, bar, (k,))

    def at(self, values: np.ndarray) -> Linkage | None:
        if np.any(values <= 0):
            raise InvalidRequest("lengths must be positive")
        lengths = np.array(self.linkage.lengths, dtype=float)
        for bar, v in zip(self.names, values, strict=True):
            lengths[self.linkage.bar_ids.index(bar)] = v
        return self.linkage.with_lengths(lengths)

    def adjustable(self) -> list[str] | None:
        return list(self.names)


@dataclass(frozen=True)
class PresetFamily:
    """Preset ``name`` with ``parameters``, and the parameters ``names`` set by a point."""

    name: str
    parameters: Mapping[str, float]
    names: tuple[str, ...]
    on_space: bool = field(default=True, init=False)

    def __post_init__(self) -> None:
        known = resolve_parameters(self.name, self.parameters)
        for k, key in enumerate(self.names):
            if key not in known:
                raise InvalidRequest(
                    f"unknown parameter {key!r} of preset {self.name!r}; known: "
                    f"{', '.join(known)}", loc=(k,))

    def at(self, values: np.ndarray) -> Linkage | None:
        """The preset at the point, or None where its lengths assemble nowhere (an empty
        configuration space)."""
        overrides = {**self.parameters, **dict(zip(self.names, map(float, values), strict=True))}
        try:
            return build_preset(self.name, overrides)
        except InvalidParameter as err:
            if err.loc == ():  # assembles at no angle
                return None
            raise

    def adjustable(self) -> list[str] | None:
        base = build_preset(self.name, self.parameters)
        named = [n for n in self.names if n in base.bar_ids]
        return named if len(named) == len(self.names) else None

    def unassembled(self, values: np.ndarray) -> Linkage | None:
        """Where :meth:`at` finds no assembly: the preset's bars with the point's lengths (off
        its configuration space, for the chain rules to prove it empty), when every swept name
        is a bar of the preset; else None."""
        try:
            if self.adjustable() is None:
                return None
            return BarFamily(build_preset(self.name, self.parameters), self.names).at(values)
        except (InvalidParameter, InvalidRequest):
            return None


Family = BarFamily | PresetFamily


@dataclass(frozen=True)
class PointResult:
    """One row of a sweep; fields not asked for (``compute``) are None.

    ``components`` is the number of components (``complete`` False when a search budget cut it
    short or no argument proves the count: it is then a lower bound; ``argument`` says what
    proves it where it is exact: derived or proved), ``critical_points`` the number of
    critical points, ``margin`` the robustness margin over the swept bars (every bar with a
    free end when the swept names are not all bars), ``windings`` the distinct rotor-turn
    patterns of the components (of the traced ones where the count is a lower bound),
    ``gated`` whether no rotor completes a turn on any component: from the chain rules where
    they apply, False where a traced component turns a rotor, True only where every component
    was traced and none does, else None; ``gated_reason`` says which, ``error`` why the point
    has no answer. ``tau_signs``: the four-bar cells whose sides a swept name sets, with their
    tau signs at the point's lengths, the gate four-bar first, as a map labels its regions
    (:func:`engine.design.region_labels.touched_cells`); None where the linkage has no such
    cell (not a rotor chain) or no linkage was built at the point."""

    values: tuple[float, ...]
    components: int | None = None
    complete: bool | None = None
    argument: Argument | None = None
    critical_points: int | None = None
    margin: float | None = None
    windings: tuple[str, ...] | None = None
    gated: bool | None = None
    gated_reason: str | None = None
    error: str | None = None
    tau_signs: tuple[FourBarCell, ...] | None = None


def _turns(linkage: Linkage, res: SpaceResult, every: bool
           ) -> tuple[tuple[str, ...], bool | None, str]:
    """The traced components' rotor-turn patterns and ``gated`` with its reason; ``every``:
    every component was traced (the count is exact and that many were traced)."""
    patterns: set[str] = set()
    turning: set[str] = set()
    unknown = False
    for comp in res.components:
        angles = rotor_angles(linkage, comp.points)
        turns = {bar: winding(a, comp.closed) for bar, a in angles.items()}
        patterns.add(",".join(f"{b}:{'?' if w is None else abs(w)}" for b, w in turns.items()))
        turning.update(b for b, w in turns.items() if w)
        unknown = unknown or any(w is None for w in turns.values())
    if turning:
        return tuple(sorted(patterns)), False, (
            f"ungated: {', '.join(sorted(turning))} turn on a traced component")
    if not res.components:
        return (), None, "no component found: nothing to turn or to gate"
    if unknown or not every:
        return tuple(sorted(patterns)), None, (
            "undecided: no traced component turns a rotor, but " + (
                "some traced curve did not close" if unknown else
                "not every component was traced (the count is a lower bound or the trace "
                "fell short of it): an untraced one could"))
    return tuple(sorted(patterns)), True, "gated: no rotor turns on any component, all traced"


def evaluate(
    family: Family,
    values: np.ndarray,
    compute: Sequence[str] = ("components",),
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
) -> PointResult:
    """Analyse the family's linkage at ``values`` (P,); an input error of this one point (e.g.
    a sampled length below zero, a linkage that is not of one degree of freedom) or a numerical
    failure becomes the row's ``error``, not an exception."""
    point = tuple(float(v) for v in values)
    try:
        return _evaluate(family, np.asarray(values, dtype=float), point, set(compute),
                         tolerances or Tolerances(), options or SpaceOptions())
    except EngineError as err:
        return PointResult(point, error=err.message)
    except NumericalFailure as err:
        return PointResult(point, error=f"no trustworthy answer: {err}")


def _evaluate(family: Family, values: np.ndarray, point: tuple[float, ...], want: set[str],
              tol: Tolerances, opt: SpaceOptions) -> PointResult:
    linkage = family.at(values)
    if linkage is None and isinstance(family, PresetFamily):
        off = family.unassembled(values)
        empty = None if off is None else derive(off)
        if off is not None and empty is not None and empty.components == 0:  # proved empty
            return PointResult(
                point,
                components=0 if "components" in want else None,
                complete=True if "components" in want else None,
                argument=ARGUMENT_DERIVED if "components" in want else None,
                critical_points=0 if "critical" in want else None,
                windings=() if "windings" in want else None,
                gated_reason=empty.gated_reason if "windings" in want else None,
                tau_signs=_cells(off, family.names))
    if linkage is None:  # empty configuration space
        return PointResult(
            point,
            components=0 if "components" in want else None,
            # (a preset that assembles at none of its sampled angles: a search, not a proof)
            complete=False if "components" in want else None,
            critical_points=0 if "critical" in want else None,
            windings=() if "windings" in want else None,
            gated=None, gated_reason=(
                "no configuration found (the preset assembles at none of its sampled angles)"
                if "windings" in want else None),
        )
    out: dict[str, Any] = {"tau_signs": _cells(linkage, family.names)}
    rule = derive(linkage) if want & {"components", "windings", "critical"} else None
    if rule is not None and "components" in want:
        out.update(components=rule.components, complete=True, argument=ARGUMENT_DERIVED)
    if rule is not None and "windings" in want and rule.windings is not None:
        out.update(windings=rule.windings, gated=rule.gated, gated_reason=rule.gated_reason)
    if rule is not None and "critical" in want and rule.no_critical:
        out["critical_points"] = 0  # the chain rules prove there is none
    res: SpaceResult | None = None
    if (want & {"components", "windings"}) - _derived(rule, out) or (
            "margin" in want and not family.on_space):
        res = explore(linkage, tol, opt, start_on_space=family.on_space, near_misses=False)
    if res is not None and "components" in want and rule is None:
        complete = res.search.complete
        total = res.search.get("components_total")
        out["components"] = (len(res.components) if complete or not isinstance(total, int)
                             else total)
        out["complete"] = complete or total is not None
        out["argument"] = res.search.argument if complete else (
            ARGUMENT_DERIVED if total is not None else None)
    if "critical" in want and "critical_points" not in out:
        if res is not None:  # (its critical search ran: no chain rule proves there is none)
            out["critical_points"] = len(res.critical_points)
        else:
            crit = find_critical_points(linkage, tol, opt, start_on_space=family.on_space)
            out["critical_points"] = len(crit.critical_points)
    if "windings" in want and "windings" not in out and res is not None:
        count = rule.components if rule is not None else (
            len(res.components) if res.search.complete else None)
        out["windings"], gated, why = _turns(linkage, res, count == len(res.components))
        if rule is not None and rule.gated is not None:  # decided without the trace
            gated, why = rule.gated, rule.gated_reason
        out["gated"], out["gated_reason"] = gated, why
    if "margin" in want:
        on_space: Linkage | None = linkage
        if not family.on_space:  # a point on the configuration space to start from
            assert res is not None
            first = res.components[0].points[:1] if res.components else None
            on_space = None if first is None else linkage.with_positions(
                positions_along(linkage, first)[0])
        if on_space is not None:
            m = robustness(on_space, family.adjustable(), tol, opt)
            out["margin"] = float(m.margin) if m.success else None
    return PointResult(point, **out)


def _cells(linkage: Linkage, names: tuple[str, ...]) -> tuple[FourBarCell, ...] | None:
    """The row's ``tau_signs`` (see :class:`PointResult`)."""
    return touched_cells(linkage, names) or None


def _derived(rule: DerivedRow | None, out: dict[str, Any]) -> set[str]:
    """What the chain rules answered of a row (nothing left to explore for it)."""
    if rule is None:
        return set()
    return {"components"} | ({"windings"} if "windings" in out else set())


def run_points(
    family: Family,
    points: np.ndarray,
    compute: Sequence[str] = ("components",),
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    deadline: Deadline | None = None,
) -> list[PointResult]:
    """:func:`evaluate` at each of ``points`` (N, P) in turn, reporting ``k / N`` points done
    to ``deadline``; stops early (fewer rows) when the deadline expires or is stopped."""
    dl = deadline or NEVER
    rows: list[PointResult] = []
    n = len(points)
    for values in points:
        if dl.expired():
            break
        rows.append(evaluate(family, values, compute, tolerances, options))
        dl.report(len(rows) / n, f"{len(rows)} of {n} points done")
    return rows


@dataclass(frozen=True)
class Summary:
    """``points``: rows; ``topologies``: rows per topology (number of components, and the
    rotor-turn patterns when windings were computed); ``gated``: rows where no rotor turns
    (``fraction_gated`` of those with an answer); ``margin``/``margin_at``: the smallest margin
    and where; ``critical``: rows at critical lengths; ``incomplete``/``errors``: rows whose
    search was cut short / that have no answer."""

    points: int
    topologies: dict[str, int]
    gated: int | None
    fraction_gated: float | None
    margin: float | None
    margin_at: tuple[float, ...] | None
    critical: int | None
    incomplete: int
    errors: int


def topology(row: PointResult) -> str | None:
    """A row's topology label, e.g. ``components=2`` or ``components=1; turns=r0:1,r1:1``."""
    if row.error is not None or (row.components is None and row.windings is None):
        return None
    parts = [] if row.components is None else [f"components={row.components}"]
    if row.windings is not None:
        parts.append(f"turns={'|'.join(row.windings)}")
    return "; ".join(parts)


def summarize(rows: Sequence[PointResult]) -> Summary:
    """Condense the rows of a sweep (see :class:`Summary`)."""
    answered = [r for r in rows if r.error is None]
    tops = Counter(t for r in answered if (t := topology(r)) is not None)
    with_gate = [r for r in answered if r.gated is not None]
    gated = sum(bool(r.gated) for r in with_gate) if with_gate else None
    margins = [r for r in answered if r.margin is not None]
    best = min(margins, key=lambda r: r.margin or 0.0) if margins else None
    crit = [r for r in answered if r.critical_points is not None]
    return Summary(
        points=len(rows),
        topologies=dict(sorted(tops.items())),
        gated=gated,
        fraction_gated=(gated / len(with_gate)) if with_gate and gated is not None else None,
        margin=None if best is None else best.margin,
        margin_at=None if best is None else best.values,
        critical=sum(1 for r in crit if r.critical_points) if crit else None,
        incomplete=sum(r.complete is False for r in answered),
        errors=len(rows) - len(answered),
    )
