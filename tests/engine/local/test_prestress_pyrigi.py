"""Agreement with PyRigi 1.3 ``is_prestress_stable`` / ``is_second_order_rigid`` (optional:
skips when PyRigi, from the ``test`` and ``bench`` extras, is not installed).

PyRigi decides only where there is one flex or one stress (it raises otherwise); there both
answers must agree. Where it raises, ours must still decide and carry a certificate that checks
independently. Known disagreements: none on this catalogue (the bench prints the same table).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import pytest

from engine.local.second_order import second_order
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from tests.engine.local.test_prestress import check_certificate

PYRIGI_CASES: dict[str, Callable[[Any], Any]] = {
    "CnSymmetricFourRegular(8)": lambda db: db.CnSymmetricFourRegular(8),
    "CnSymmetricFourRegular(10)": lambda db: db.CnSymmetricFourRegular(10),
    "CnSymmetricWithFixedVertex(8)": lambda db: db.CnSymmetricWithFixedVertex(8),
    "ThreePrism()": lambda db: db.ThreePrism(),
    "ThreePrism(parallel)": lambda db: db.ThreePrism("parallel"),
    "ThreePrism(flexible)": lambda db: db.ThreePrism("flexible"),
    "Octahedron(regular)": lambda db: db.Octahedron("regular"),
    "Octahedron(Bricard_line)": lambda db: db.Octahedron("Bricard_line"),
    "Octahedron(Bricard_plane)": lambda db: db.Octahedron("Bricard_plane"),
    "CompleteBipartite(3,3,dixonI)": lambda db: db.CompleteBipartite(3, 3, "dixonI"),
    "CompleteBipartite(4,4,dixonI)": lambda db: db.CompleteBipartite(4, 4, "dixonI"),
    "CompleteBipartite(3,3)": lambda db: db.CompleteBipartite(3, 3),
    "Frustum(3)": lambda db: db.Frustum(3),
    "Frustum(4)": lambda db: db.Frustum(4),
    "Frustum(5)": lambda db: db.Frustum(5),
    "Cube": lambda db: db.Cube(),
    # two stresses and two flexes: PyRigi raises; Connelly-Whiteley (1996) prove it second-order
    # rigid and not prestress stable
    "SecondOrderRigid": lambda db: db.SecondOrderRigid(),
}


def to_linkage(framework: Any) -> Linkage:
    """The same positions and edges as an engine linkage (nothing pinned)."""
    real = framework.realization(as_points=True, numerical=True)
    order = sorted(real, key=str)
    vertices = [VertexSpec(str(v), [float(x) for x in real[v]]) for v in order]
    bars = [BarSpec(f"e{i}", (str(u), str(w)))
            for i, (u, w) in enumerate(framework.graph.edge_list())]
    return build_linkage(framework.dim, vertices, bars)


def ours(framework: Any) -> tuple[bool | None, bool | None, int, int]:
    res = second_order(to_linkage(framework))
    pre = res.prestress
    return (pre.prestress_stable, pre.second_order_rigid, res.rigidity.self_stresses.shape[0],
            res.rigidity.dof)


def theirs(framework: Any) -> tuple[bool | None, bool | None]:
    """PyRigi's answers; None where it raises (not implemented for several of both)."""
    out: list[bool | None] = []
    for method in ("is_prestress_stable", "is_second_order_rigid"):
        try:
            out.append(bool(getattr(framework, method)(numerical=True)))
        except ValueError:
            out.append(None)
    return out[0], out[1]


@pytest.mark.parametrize("name", list(PYRIGI_CASES))
def test_agrees_with_pyrigi(name):
    db = pytest.importorskip("pyrigi.frameworkDB")
    framework = PYRIGI_CASES[name](db)
    stable, rigid, s, k = ours(framework)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        their_stable, their_rigid = theirs(framework)
    if s <= 1 or k <= 1:
        assert (their_stable, their_rigid) == (stable, rigid)
    else:
        assert their_stable is None  # PyRigi 1.3 does not decide several stresses and flexes
    assert stable is not None and rigid is not None
    lk = to_linkage(framework)
    check_certificate(lk, second_order(lk).prestress)
