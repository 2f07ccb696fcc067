"""Every preset with its default parameters through every synchronous POST endpoint that its
linkage is meaningful for (issue 11): the cases, not tests; used by the tests and by
``bench/bench_presets.py`` (which loads this file by path, so it imports nothing of the project).

"Meaningful" is read off the linkage, never off a list of preset names:

* first and second order and the linkage figure: every linkage;
* everything that traces (critical points, configuration space, splitting, robustness, critical
  values, their figures): one degree of freedom with something fixed, ``M - E = 1`` counted as
  ``engine.space.configuration_space.results.require_one_dof`` does (``M`` free coordinates, ``E``
  bars with a free end);
* the configuration-space figure: also planar, with two rotors (bars with exactly one pinned end)
  as axes (3D linkages get a 422 naming ``linkage.dimension``);
* critical values: the first two bars with a free end as axes, box ``[0.8 L, 1.2 L]`` each;
* splitting: the first bar with a free end changed by ``1e-3`` of its length;
* two degrees of freedom (``M - E = 2`` with something fixed, issue 25): the configuration
  space (its surfaces), splitting (as above), and in the plane the configuration-space figure;
  the endpoints that need one degree of freedom (:data:`ONE_DOF_ONLY`) answer them a 422 naming
  ``linkage``, asked by ``tests/service/test_every_preset.py``;
* design: only where ``/v1/analysis/critical-points`` (asked through ``client``) reports a
  branch point: the first one as target with sign +1, every bar with a free end adjustable.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, Protocol

Json = dict[str, Any]


class Client(Protocol):
    """What is used of an ``httpx.Client`` (or of ``tests.conftest.ApiClient``)."""

    def get(self, url: str, **kw: Any) -> Any: ...

    def post(self, url: str, **kw: Any) -> Any: ...


ALWAYS = ("/v1/analysis/rigidity", "/v1/analysis/second-order", "/v1/figures/linkage")
TRACING = ("/v1/analysis/critical-points", "/v1/analysis/configuration-space",
           "/v1/analysis/splitting", "/v1/analysis/robustness", "/v1/analysis/critical-values",
           "/v1/figures/configuration-space", "/v1/figures/critical-values",
           "/v1/figures/splitting")
SURFACES = ("/v1/analysis/configuration-space", "/v1/analysis/splitting",
            "/v1/figures/configuration-space")
ONE_DOF_ONLY = ("/v1/analysis/critical-points", "/v1/analysis/robustness",
                "/v1/analysis/critical-values")
DESIGN = "/v1/design/splitting"
SPLIT_FRACTION = 1e-3
BOX = (0.8, 1.2)
#: Presets beyond their default parameters (issue 30: presets up to 100 rotors, the paper's gate)
#: as ``(name, query)``.
VARIANTS = (("kl-chain", "n=100"), ("gated-kl-chain", "n=4&gate=2"))
#: The gate slice of issue 30: the 4-rotor gated chain's map in (L2, D) over [1, 3] x [1, 3.5].
GATE_SLICE_AXES = ({"bar": "L2", "min": 1.0, "max": 3.0}, {"bar": "D", "min": 1.0, "max": 3.5})


def _fixed_axes(vertex: Json, dim: int) -> list[bool]:
    fixed = vertex.get("fixed", False)
    return [fixed] * dim if isinstance(fixed, bool) else list(fixed)


def _pinned(linkage: Json) -> set[str]:
    dim = int(linkage.get("dimension", 2))
    return {v["id"] for v in linkage["vertices"] if all(_fixed_axes(v, dim))}


def free_bars(linkage: Json) -> list[Json]:
    """Bars with a free end (the ones whose length a request may change), in request order."""
    pinned = _pinned(linkage)
    return [b for b in linkage.get("bars", []) if not set(b["ends"]) <= pinned]


def rotors(linkage: Json) -> list[str]:
    """Bars with exactly one pinned end (the configuration-space figure's axes)."""
    pinned = _pinned(linkage)
    return [b["id"] for b in linkage.get("bars", []) if len(set(b["ends"]) & pinned) == 1]


def dof(linkage: Json) -> int | None:
    """``M - E`` with something fixed (None when nothing is)."""
    dim = int(linkage.get("dimension", 2))
    axes = [_fixed_axes(v, dim) for v in linkage["vertices"]]
    m = sum(not f for fixed in axes for f in fixed)
    return m - len(free_bars(linkage)) if any(any(fixed) for fixed in axes) else None


def one_dof(linkage: Json) -> bool:
    """``M - E = 1`` with something fixed: the linkage can be traced."""
    return dof(linkage) == 1


def two_dof(linkage: Json) -> bool:
    """``M - E = 2`` with something fixed: its configuration space is made of surfaces."""
    return dof(linkage) == 2


def bar_length(linkage: Json, bar: Json) -> float:
    if bar.get("length") is not None:
        return float(bar["length"])
    pos = {v["id"]: v["position"] for v in linkage["vertices"]}
    return math.dist(pos[bar["ends"][0]], pos[bar["ends"][1]])


def bodies(linkage: Json) -> Iterator[tuple[str, Json]]:
    """``(endpoint, body)`` for every endpoint but design that ``linkage`` is meaningful for."""
    for path in ALWAYS:
        yield path, {"linkage": linkage}
    bars = free_bars(linkage)
    if not (one_dof(linkage) or two_dof(linkage)):
        return
    first = bars[0]
    split = {"linkage": linkage,
             "perturbation": {first["id"]: SPLIT_FRACTION * bar_length(linkage, first)}}
    if two_dof(linkage):
        planar = int(linkage.get("dimension", 2)) == 2 and len(rotors(linkage)) >= 2
        for path in SURFACES[:2] + (SURFACES[2:] if planar else ()):
            yield path, split if path.endswith("/splitting") else {"linkage": linkage}
        return
    values = {"linkage": linkage, "axes": [
        {"bar": b["id"], "min": BOX[0] * bar_length(linkage, b),
         "max": BOX[1] * bar_length(linkage, b)} for b in bars[:2]]}
    skip = {"/v1/figures/configuration-space": len(rotors(linkage)) < 2
            or int(linkage.get("dimension", 2)) != 2,
            "/v1/analysis/critical-values": len(bars) < 2,
            "/v1/figures/critical-values": len(bars) < 2}
    for path in TRACING:
        if not skip.get(path, False):
            yield path, split if path.endswith("/splitting") else values \
                if path.endswith("/critical-values") else {"linkage": linkage}


def design_body(client: Client, linkage: Json) -> Json | None:
    """The design request for the first branch point ``critical-points`` reports (None when it
    reports none, or does not answer 200)."""
    r = client.post("/v1/analysis/critical-points", json={"linkage": linkage})
    if r.status_code != 200:
        return None
    kinds = [cp["kind"] for cp in r.json()["critical_points"]]
    if "branch" not in kinds:
        return None
    return {"linkage": linkage, "targets": [{"branch_point": kinds.index("branch"), "sign": 1}],
            "adjustable": [b["id"] for b in free_bars(linkage)]}


def gate_slice(client: Client) -> Json:
    """The body of issue 30's gate slice (default options: resolution 48, the default budget)."""
    got = client.get("/v1/presets/gated-kl-chain?n=4&gate=2")
    assert got.status_code == 200, got.text
    return {"linkage": got.json(), "axes": [dict(a) for a in GATE_SLICE_AXES]}


def variant_linkages(client: Client) -> Iterator[tuple[str, Json]]:
    """``(label, linkage)`` of every preset with its defaults, then of :data:`VARIANTS` (the
    label is the preset's name with its query, e.g. ``kl-chain?n=100``)."""
    listing = client.get("/v1/presets")
    assert listing.status_code == 200, listing.text
    for label in [info["name"] for info in listing.json()] + [f"{n}?{q}" for n, q in VARIANTS]:
        got = client.get(f"/v1/presets/{label}")
        assert got.status_code == 200, (label, got.text)
        yield label, got.json()


def preset_cases(client: Client, only: list[str] | None = None
                 ) -> Iterator[tuple[str, str, Json]]:
    """``(preset, endpoint, body)`` for every preset (or those in ``only``) with its default
    parameters and every synchronous POST endpoint its linkage is meaningful for."""
    listing = client.get("/v1/presets")
    assert listing.status_code == 200, listing.text
    for info in listing.json():
        name = info["name"]
        if only is not None and name not in only:
            continue
        got = client.get(f"/v1/presets/{name}")
        assert got.status_code == 200, (name, got.text)
        linkage = got.json()
        for path, body in bodies(linkage):
            yield name, path, body
        if one_dof(linkage) and (design := design_body(client, linkage)) is not None:
            yield name, DESIGN, design
