"""Named linkages from the paper, each assembled on a point of its configuration space.

Geometry (all planar; angles in radians, measured from the +x axis):

- ``four-bar``: pins ``P1 = (0, 0)``, ``P2 = (a, 0)``; rotor ``L1`` from ``P1`` to ``A`` at angle
  ``theta``; coupler ``L2`` from ``A`` to ``B``; rotor ``L3`` from ``P2`` to ``B``.
- ``three-rotor``: pins ``P1 = (0, 0)``, ``P2 = (a, 0)``, ``P3 = P2 + a (cos phi, sin phi)``
  (``phi = 0`` puts the pins on a line); rotors ``r1, r2, r3`` to tips ``A, B, C``; couplers
  ``L1`` (``A-B``) and ``L2`` (``B-C``); the middle rotor at angle ``theta``.
- ``kl-chain``: pins ``P0 .. P{n-1}`` at ``(k a, 0)``; rotors ``r{k}`` of length ``r`` to tips
  ``T{k}``; bars ``l{k}`` of length ``l`` from ``T{k}`` to ``T{k+1}``; rotor 0 at angle ``theta``.
- ``gated-kl-chain``: the chain plus a slider pin ``G`` at ``P{gate} + (0, -D)`` (x fixed, y
  free) held by bar ``D`` from ``P{gate}``, a rocker ``L1`` from ``G`` to ``R`` and a bar ``L2``
  from ``T{gate}`` to ``R``; the gate rotor at angle ``theta``, the chain solved outwards.

Every preset is assembled at ``theta`` or, where it does not assemble there, at the first angle
after it (in steps of half a degree) where it does.

Where two assemblies exist, ``side = +1`` takes the intersection to the left of the line from the
first circle's centre to the second's, ``-1`` the other one.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from engine.catalogue.catalogue import CATALOGUE, circle_intersection, polar
from engine.catalogue.mechanisms import LENGTHS as MECHANISM_LENGTHS
from engine.catalogue.mechanisms import MECHANISMS
from engine.model.errors import InvalidLinkage, InvalidParameter, LimitExceeded, UnknownPreset
from engine.model.linkage import BarSpec, Limits, Linkage, VertexSpec, build_linkage

Params = dict[str, float]
Specs = tuple[list[VertexSpec], list[BarSpec]]


def _first_assembly(
    theta: float, attempt: Callable[[float], Specs | None], what: str
) -> Specs:
    """``attempt(angle)`` at ``theta``, else at the first angle after it (0.5 degree steps)
    where the linkage assembles; a clear error when it assembles nowhere."""
    for angle in theta + np.linspace(0.0, 2 * np.pi, 721)[:-1]:
        specs = attempt(float(angle))
        if specs is not None:
            return specs
    raise InvalidParameter(
        f"the lengths admit no configuration: {what} assembles at no angle", loc=()
    )


def _four_bar(p: Params) -> Specs:
    pin1, pin2 = np.zeros(2), np.array([p["a"], 0.0])

    def attempt(theta: float) -> Specs | None:
        tip_a = polar(theta, p["L1"])
        tip_b = circle_intersection(tip_a, p["L2"], pin2, p["L3"], p["side"])
        if tip_b is None:
            return None
        vertices = [
            VertexSpec("P1", pin1.tolist(), True),
            VertexSpec("P2", pin2.tolist(), True),
            VertexSpec("A", tip_a.tolist()),
            VertexSpec("B", tip_b.tolist()),
        ]
        bars = [
            BarSpec("L1", ("P1", "A"), p["L1"]),
            BarSpec("L2", ("A", "B"), p["L2"]),
            BarSpec("L3", ("P2", "B"), p["L3"]),
        ]
        return vertices, bars

    return _first_assembly(p["theta"], attempt, "the four-bar")


def _three_rotor(p: Params) -> Specs:
    pins = [np.zeros(2), np.array([p["a"], 0.0])]
    pins.append(pins[1] + polar(p["phi"], p["a"]))

    def attempt(theta: float) -> Specs | None:
        tip_b = pins[1] + polar(theta, p["r2"])
        tip_a = circle_intersection(tip_b, p["L1"], pins[0], p["r1"], p["side1"])
        tip_c = circle_intersection(tip_b, p["L2"], pins[2], p["r3"], p["side3"])
        if tip_a is None or tip_c is None:
            return None
        vertices = [VertexSpec(f"P{k + 1}", pins[k].tolist(), True) for k in range(3)] + [
            VertexSpec("A", tip_a.tolist()),
            VertexSpec("B", tip_b.tolist()),
            VertexSpec("C", tip_c.tolist()),
        ]
        bars = [
            BarSpec("r1", ("P1", "A"), p["r1"]),
            BarSpec("r2", ("P2", "B"), p["r2"]),
            BarSpec("r3", ("P3", "C"), p["r3"]),
            BarSpec("L1", ("A", "B"), p["L1"]),
            BarSpec("L2", ("B", "C"), p["L2"]),
        ]
        return vertices, bars

    return _first_assembly(p["theta"], attempt, "the three-rotor")


def _chain_tips(p: Params, n: int, start: int, start_tip: np.ndarray) -> np.ndarray | None:
    """Tips of a KL chain (n, 2) solved outwards from rotor ``start``; None if one is missing."""
    pins = np.column_stack([np.arange(n) * p["a"], np.zeros(n)])
    tips = np.empty((n, 2))
    tips[start] = start_tip
    for k in range(start + 1, n):
        tip = circle_intersection(tips[k - 1], p["l"], pins[k], p["r"], p["side"])
        if tip is None:
            return None
        tips[k] = tip
    for k in range(start - 1, -1, -1):
        tip = circle_intersection(tips[k + 1], p["l"], pins[k], p["r"], -p["side"])
        if tip is None:
            return None
        tips[k] = tip
    return tips


def _chain_specs(p: Params, n: int, tips: np.ndarray) -> Specs:
    vertices = [VertexSpec(f"P{k}", [k * p["a"], 0.0], True) for k in range(n)]
    vertices += [VertexSpec(f"T{k}", tips[k].tolist()) for k in range(n)]
    bars = [BarSpec(f"r{k}", (f"P{k}", f"T{k}"), p["r"]) for k in range(n)]
    bars += [BarSpec(f"l{k}", (f"T{k}", f"T{k + 1}"), p["l"]) for k in range(n - 1)]
    return vertices, bars


def _kl_chain(p: Params) -> Specs:
    n = int(p["n"])

    def attempt(theta: float) -> Specs | None:
        tips = _chain_tips(p, n, 0, polar(theta, p["r"]))
        return None if tips is None else _chain_specs(p, n, tips)

    return _first_assembly(p["theta"], attempt, "the chain")


def _gated_kl_chain(p: Params) -> Specs:
    n, gate = int(p["n"]), int(p["gate"])
    pin = np.array([gate * p["a"], 0.0])
    slider = pin + np.array([0.0, -p["D"]])

    def attempt(theta: float) -> Specs | None:
        tip = pin + polar(theta, p["r"])
        rocker = circle_intersection(tip, p["L2"], slider, p["L1"], p["side"])
        tips = None if rocker is None else _chain_tips(p, n, gate, tip)
        if rocker is None or tips is None:
            return None
        vertices, bars = _chain_specs(p, n, tips)
        vertices += [
            VertexSpec("G", slider.tolist(), [True, False]),
            VertexSpec("R", rocker.tolist()),
        ]
        bars += [
            BarSpec("D", (f"P{gate}", "G"), p["D"]),
            BarSpec("L1", ("G", "R"), p["L1"]),
            BarSpec("L2", (f"T{gate}", "R"), p["L2"]),
        ]
        return vertices, bars

    return _first_assembly(p["theta"], attempt, "the gated chain")


@dataclass(frozen=True)
class Preset:
    """A named linkage family."""

    name: str
    description: str
    parameters: Mapping[str, float]
    integers: frozenset[str]
    build: Callable[[Params], Specs]
    dimension: int = 2


_LENGTHS = {"a", "L1", "L2", "L3", "r", "l", "r1", "r2", "r3", "D"} | MECHANISM_LENGTHS
_SIDES = {"side", "side1", "side3"}

PRESETS: dict[str, Preset] = {
    p.name: p
    for p in (
        Preset(
            "four-bar",
            "Planar four-bar: ground a between pins P1 and P2, rotor L1 (P1-A), coupler L2 (A-B), "
            "rotor L3 (P2-B); rotor L1 at angle theta. a = L1 = L2 = L3 is the paper's "
            "equilateral four-bar with three branch points.",
            {"a": 1.0, "L1": 1.0, "L2": 1.0, "L3": 1.0, "theta": np.pi / 3, "side": 1.0},
            frozenset(),
            _four_bar,
        ),
        Preset(
            "three-rotor",
            "Three rotors r1, r2, r3 on pins P1 = (0,0), P2 = (a,0), "
            "P3 = P2 + a(cos phi, sin phi), tips joined by couplers L1 (A-B) and L2 (B-C); middle "
            "rotor at angle theta. All "
            "lengths equal and phi off the line give the paper's twelve branch points.",
            {
                "a": 1.0,
                "r1": 1.0,
                "r2": 1.0,
                "r3": 1.0,
                "L1": 1.0,
                "L2": 1.0,
                "phi": np.pi / 2,
                "theta": 1.2,
                "side1": -1.0,
                "side3": -1.0,
            },
            frozenset(),
            _three_rotor,
        ),
        Preset(
            "kl-chain",
            "Kane-Lubensky chain: n rotors of length r on pins spaced a along x, consecutive tips "
            "joined by bars of length l; rotor 0 at angle theta. r = l = 3a/2 supports the "
            "spinner soliton.",
            {"n": 10, "a": 1.0, "r": 1.5, "l": 1.5, "theta": 1.3, "side": 1.0},
            frozenset({"n"}),
            _kl_chain,
        ),
        Preset(
            "gated-kl-chain",
            "Kane-Lubensky chain with the paper's gate on rotor `gate`: a slider pin G held at "
            "distance D below that rotor's pin by bar D, a rocker L1 (G-R) and a bar L2 from the "
            "rotor's tip to R. With r = l = 3a/2 and L1 = L2 = 2a the chain is ungated for "
            "D < 5a/2 and gated above.",
            {
                "n": 10,
                "a": 1.0,
                "r": 1.5,
                "l": 1.5,
                "gate": 5,
                "D": 2.0,
                "L1": 2.0,
                "L2": 2.0,
                "theta": 1.3,
                "side": 1.0,
            },
            frozenset({"n", "gate"}),
            _gated_kl_chain,
        ),
    )
}
# 3D and rigidity-theory frameworks (engine/catalogue/catalogue.py)
PRESETS.update(
    {e.name: Preset(e.name, e.description, e.parameters, e.integers, e.build, e.dimension)
     for e in CATALOGUE + MECHANISMS}
)


@dataclass(frozen=True)
class Bounds:
    """The values one preset parameter may take, as :func:`resolve_parameters` enforces them
    (the service publishes them as the parameter's schema).

    ``minimum``/``maximum`` are inclusive, ``exclusive_minimum`` is not; ``multiple_of`` is 1
    for an integer (2 for an even one); ``choices`` lists the only values allowed; ``below``
    names another parameter this one must stay strictly under (``gate < n``)."""

    minimum: float | None = None
    exclusive_minimum: float | None = None
    maximum: float | None = None
    multiple_of: float | None = None
    choices: tuple[float, ...] = ()
    below: str | None = None


#: Chain lengths ``n`` (inclusive) per preset; 20000 where not listed.
_N_RANGE = {"rotor-chain-3d": (2.0, 2000.0), "cn-symmetric-four-regular": (8.0, 200.0)}
_N_MAX = 20_000.0
_EVEN = {"cn-symmetric-four-regular"}


def parameter_bounds(name: str) -> dict[str, Bounds]:
    """The bounds of every parameter of preset ``name`` (a parameter without any has an empty
    :class:`Bounds`: any finite value is taken, and only the geometry may refuse it).

    Examples
    --------
    >>> parameter_bounds("gated-kl-chain")["gate"]
    Bounds(minimum=0.0, exclusive_minimum=None, maximum=19999.0, multiple_of=1.0, choices=(), \
below='n')
    """
    preset = PRESETS[name]
    out: dict[str, Bounds] = {}
    for key in preset.parameters:
        step = (2.0 if name in _EVEN else 1.0) if key == "n" else (
            1.0 if key in preset.integers else None)
        if key in _LENGTHS or (key == "h" and name == "rotor-chain-3d"):
            out[key] = Bounds(exclusive_minimum=0.0)
        elif key in _SIDES:
            out[key] = Bounds(choices=(-1.0, 1.0))
        elif key == "n":
            low, high = _N_RANGE.get(name, (2.0, _N_MAX))
            out[key] = Bounds(minimum=low, maximum=high, multiple_of=step)
        elif key == "gate":
            n_max = _N_RANGE.get(name, (2.0, _N_MAX))[1]
            out[key] = Bounds(minimum=0.0, maximum=n_max - 1, multiple_of=step, below="n")
        else:
            out[key] = Bounds(multiple_of=step)
    return out


def _check_bounds(key: str, value: float, bounds: Bounds, params: Params) -> None:
    """Raise :class:`InvalidParameter` at ``key`` when ``value`` is outside ``bounds``."""
    if bounds.multiple_of is not None and value % bounds.multiple_of != 0:
        what = "an integer" if bounds.multiple_of == 1 else f"a multiple of {bounds.multiple_of:g}"
        raise InvalidParameter(f"must be {what}, got {value!r}", loc=(key,))
    if bounds.exclusive_minimum is not None and not value > bounds.exclusive_minimum:
        raise InvalidParameter(f"length must be positive, got {value!r}", loc=(key,))
    if bounds.choices and value not in bounds.choices:
        raise InvalidParameter(
            f"must be one of {', '.join(f'{c:g}' for c in bounds.choices)}, got {value!r}",
            loc=(key,))
    low = -np.inf if bounds.minimum is None else bounds.minimum
    high = np.inf if bounds.maximum is None else bounds.maximum
    if bounds.below is not None:
        high = min(high, params[bounds.below] - 1)
    if not low <= value <= high:
        raise InvalidParameter(f"{key} must lie in [{low:g}, {high:g}], got {value:g}"
                               + (f" (below {bounds.below} = {params[bounds.below]:g})"
                                  if bounds.below else ""), loc=(key,))


def resolve_parameters(name: str, overrides: Mapping[str, float] | None = None) -> Params:
    """Defaults of preset ``name`` updated with ``overrides``, validated against
    :func:`parameter_bounds`."""
    if name not in PRESETS:
        raise UnknownPreset(
            f"no preset named {name!r}; known: {', '.join(sorted(PRESETS))}", loc=("name",)
        )
    preset = PRESETS[name]
    params: Params = dict(preset.parameters)
    for key, value in (overrides or {}).items():
        if key not in params:
            raise InvalidParameter(
                f"unknown parameter {key!r} for {name!r}; known: {', '.join(params)}",
                loc=(key,),
            )
        value = float(value)
        if not np.isfinite(value):
            raise InvalidParameter("must be finite", loc=(key,))
        params[key] = value
    for key, bounds in parameter_bounds(name).items():
        _check_bounds(key, params[key], bounds, params)
    return params


#: A generated linkage must satisfy its own lengths to this, relative to its longest bar.
PRESET_ASSEMBLY_RTOL = 1e-8


def _check_generated(linkage: Linkage) -> None:
    """What :func:`build_linkage` does not check of a generated linkage: it lies on its own
    configuration space (every bar as long as its target)."""
    scale = float(np.max(linkage.lengths)) if linkage.n_bars else 0.0
    off = np.abs(linkage.bar_lengths() - linkage.lengths)
    if linkage.n_bars and not float(np.max(off)) <= PRESET_ASSEMBLY_RTOL * scale:
        k = int(np.argmax(off))
        raise InvalidLinkage(
            f"bar {linkage.bar_ids[k]!r} is {float(off[k]):.3g} off its length "
            f"{float(linkage.lengths[k]):.6g} (float64 cannot hold the geometry)"
        )


def _blame(name: str, params: Params, overrides: Mapping[str, float] | None,
           reason: str) -> InvalidParameter:
    """The error for parameters that produce no valid linkage, naming the given ones."""
    given = [k for k in (overrides or {}) if params[k] != PRESETS[name].parameters[k]]
    which = ", ".join(f"{k} = {params[k]:g}" for k in given) or "the default parameters"
    return InvalidParameter(
        f"{name} with {which} gives no valid linkage: {reason}",
        loc=(given[0],) if len(given) == 1 else (),
    )


def build_preset(
    name: str, overrides: Mapping[str, float] | None = None, limits: Limits | None = None
) -> Linkage:
    """Build preset ``name`` with parameter ``overrides``.

    Whatever the preset, the linkage it generates is checked like a client's (finite
    coordinates within range, positive bar lengths, sizes within ``limits``) and against its
    own lengths; parameters that fail (e.g. lengths whose squares overflow float64) raise
    :class:`InvalidParameter` naming the parameters that were given.

    Examples
    --------
    >>> lk = build_preset("four-bar", {"L2": 1.1})
    >>> lk.bar_ids, round(float(lk.lengths[1]), 3)
    (('L1', 'L2', 'L3'), 1.1)
    """
    params = resolve_parameters(name, overrides)
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            vertices, bars = PRESETS[name].build(params)
            linkage = build_linkage(PRESETS[name].dimension, vertices, bars, limits)
            _check_generated(linkage)
    except ArithmeticError:  # overflow (Python floats) or FloatingPointError (numpy)
        raise _blame(name, params, overrides, "its coordinates overflow float64") from None
    except (InvalidLinkage, LimitExceeded) as err:
        raise _blame(name, params, overrides, err.message) from None
    return linkage
