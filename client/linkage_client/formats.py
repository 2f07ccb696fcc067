"""Linkages to and from the formats of the field: PyRigi, networkx, pylinkage and FOLD 1.1.

Every conversion keeps the graph (vertex and bar ids), the positions and the bar lengths; what a
format cannot hold is refused with a ``ValueError`` rather than dropped:

========================  ====================================================================
format                    holds
========================  ====================================================================
``networkx.Graph``        node attributes ``pos`` (tuple), ``fixed``; edge attributes ``id``,
                          ``length``; graph attribute ``dimension``
``pyrigi.Framework``      its graph (nodes are the vertex ids, with the same attributes as the
                          networkx graph) and its realization; lengths are the realization's
``pylinkage`` JSON        ``mechanism_to_dict`` form: ground joints (pinned), revolute joints,
                          prismatic joints (sliders along an axis), one link per bar; planar
``FOLD 1.1``              ``vertices_coords``, ``edges_vertices``, ``edges_length``; ids and pins
                          in the custom fields ``vertices_linkage:id``, ``edges_linkage:id``,
                          ``vertices_linkage:fixed``
========================  ====================================================================

The libraries are imported only by the functions that need their objects (install them with
the client's ``formats`` extra); the JSON forms (pylinkage, FOLD) need none.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import combinations
from typing import Any

import numpy as np

from linkage_client.models import Bar, Linkage, Vertex, linkage_json

#: Relative disagreement between a bar's given length and its ends' distance beyond which a
#: format that keeps positions only (PyRigi, pylinkage) cannot represent the linkage.
LENGTH_RTOL = 1e-9
#: Namespace of the FOLD custom fields (the spec's "Custom Properties": a colon in the key).
FOLD_NS = "linkage"
FOLD_SPEC = 1.1
#: ``edges_assignment`` values of FOLD 1.1 (1.2 adds ``C`` and ``J``, read here as well).
FOLD_ASSIGNMENTS = ("B", "M", "V", "F", "U", "C", "J")

LinkageIn = Linkage | Mapping[str, Any]


def _linkage(linkage: LinkageIn) -> Linkage:
    return linkage if isinstance(linkage, Linkage) else Linkage.from_json(linkage)


def _fixed(value: Any, dimension: int) -> bool | tuple[bool, ...]:
    if isinstance(value, bool | np.bool_):
        return bool(value)
    flags = tuple(bool(v) for v in value)
    if len(flags) != dimension:
        raise ValueError(f"fixed {list(flags)} needs one flag per axis ({dimension})")
    return flags


def _check_lengths(linkage: Linkage, fmt: str) -> None:
    """A format that keeps positions only must get lengths that the positions give."""
    pos = {v.id: np.asarray(v.position, dtype=np.float64) for v in linkage.vertices}
    for b in linkage.bars:
        if b.length is None:
            continue
        dist = float(np.linalg.norm(pos[b.ends[0]] - pos[b.ends[1]]))
        if abs(dist - b.length) > LENGTH_RTOL * max(abs(b.length), dist, 1e-300):
            raise ValueError(f"bar {b.id!r} has length {b.length} but its ends are {dist} apart: "
                             f"{fmt} keeps positions only (project the linkage first)")


def _simple(linkage: Linkage, fmt: str) -> None:
    seen: dict[frozenset[str], str] = {}
    for b in linkage.bars:
        pair = frozenset(b.ends)
        if len(pair) == 1:
            raise ValueError(f"bar {b.id!r} joins {b.ends[0]!r} to itself: {fmt} has no loops")
        if pair in seen:
            raise ValueError(f"bars {seen[pair]!r} and {b.id!r} join the same vertices: "
                             f"{fmt} holds a simple graph")
        seen[pair] = b.id


# ---------------------------------------------------------------- networkx


def to_networkx(linkage: LinkageIn) -> Any:
    """A ``networkx.Graph``: nodes are vertex ids with ``pos`` and ``fixed``, edges carry the
    bar's ``id`` and ``length`` (the given one, else the distance of its ends)."""
    import networkx as nx

    lk = _linkage(linkage)
    _simple(lk, "a networkx Graph")
    graph = nx.Graph(dimension=lk.dimension)
    for v in lk.vertices:
        graph.add_node(v.id, pos=tuple(float(x) for x in v.position), fixed=v.fixed)
    lengths = lk.lengths()
    for b in lk.bars:
        graph.add_edge(*b.ends, id=b.id, length=lengths[b.id])
    return graph


def from_networkx(graph: Any, positions: Mapping[Any, Sequence[float]] | None = None, *,
                  pos: str = "pos", fixed: str = "fixed", bar_id: str = "id",
                  length: str = "length") -> Linkage:
    """A linkage from a networkx graph with positions (node attribute ``pos``, or the mapping
    ``positions`` as ``networkx.draw`` takes it). Nodes become vertices ``str(node)``; an edge's
    ``id`` and ``length`` attributes are kept where present (ids default to ``"u-v"``)."""
    if graph.is_directed() or graph.is_multigraph():
        raise ValueError("a linkage is a simple undirected graph (use networkx.Graph)")
    where = positions if positions is not None else {n: d.get(pos)
                                                     for n, d in graph.nodes(data=True)}
    vertices = []
    for node, data in graph.nodes(data=True):
        p = where.get(node)
        if p is None:
            raise ValueError(f"node {node!r} has no position ({pos!r} attribute)")
        vertices.append((str(node), tuple(float(x) for x in p), data.get(fixed, False)))
    dims = {len(p) for _, p, _ in vertices}
    dimension = int(graph.graph.get("dimension", max(dims, default=2)))
    if dims - {dimension}:
        raise ValueError(f"positions of {sorted(dims)} coordinates in a {dimension}D graph")
    bars = [Bar(str(d.get(bar_id, f"{u}-{v}")), (str(u), str(v)),
                None if d.get(length) is None else float(d[length]))
            for u, v, d in graph.edges(data=True)]
    return Linkage(tuple(Vertex(i, p, _fixed(f, dimension)) for i, p, f in vertices),
                   tuple(bars), dimension)


# ---------------------------------------------------------------- PyRigi


def to_pyrigi(linkage: LinkageIn) -> Any:
    """A ``pyrigi.Framework`` (graph and realization). PyRigi has no pins: each vertex keeps
    ``fixed`` as a node attribute, each edge its bar ``id``. Lengths are the realization's, so
    a bar whose given length its ends do not realise is refused."""
    from pyrigi import Framework, Graph

    lk = _linkage(linkage)
    _simple(lk, "a PyRigi Graph")
    _check_lengths(lk, "a PyRigi Framework")
    graph = Graph()
    for v in lk.vertices:
        graph.add_node(v.id, fixed=v.fixed)
    for b in lk.bars:
        graph.add_edge(*b.ends, id=b.id)
    return Framework(graph, {v.id: [float(x) for x in v.position] for v in lk.vertices})


def from_pyrigi(framework: Any, fixed: Mapping[Any, Any] | None = None) -> Linkage:
    """A linkage from a ``pyrigi.Framework``: its graph, its realization (numerically), and
    pins from ``fixed`` (vertex -> bool or per-axis flags) or the ``fixed`` node attribute."""
    graph = framework.graph
    points = framework.realization(as_points=True, numerical=True)
    dimension = int(framework.dim)
    pins = fixed if fixed is not None else {n: d.get("fixed", False)
                                            for n, d in graph.nodes(data=True)}
    vertices = tuple(Vertex(str(n), tuple(float(x) for x in points[n]),
                            _fixed(pins.get(n, False), dimension)) for n in graph.nodes)
    bars = tuple(Bar(str(d.get("id", f"{u}-{v}")), (str(u), str(v)))
                 for u, v, d in graph.edges(data=True))
    return Linkage(vertices, bars, dimension)


# ---------------------------------------------------------------- pylinkage


def to_pylinkage(linkage: LinkageIn, name: str = "") -> dict[str, Any]:
    """pylinkage's mechanism JSON (``pylinkage.mechanism.mechanism_from_dict`` reads it).

    Pinned vertices are ``ground`` joints (joined by one ``ground`` link), sliders ``prismatic``
    joints along their free axis, the others ``revolute``; each bar is a binary ``link``.
    Planar linkages only; lengths are the positions' (pylinkage stores none).
    """
    lk = _linkage(linkage)
    if lk.dimension != 2:
        raise ValueError("pylinkage mechanisms are planar: the linkage is 3D")
    _check_lengths(lk, "pylinkage's mechanism JSON")
    joints: list[dict[str, Any]] = []
    ground: list[str] = []
    for v in lk.vertices:
        joint: dict[str, Any] = {"id": v.id, "position": [float(x) for x in v.position]}
        if v.fixed is True:
            joint["type"] = "ground"
            ground.append(v.id)
        elif v.fixed is False or not any(v.fixed):
            joint["type"] = "revolute"
        elif all(v.fixed):
            joint["type"] = "ground"
            ground.append(v.id)
        else:  # a slider: free along the one axis not pinned
            axis = [0.0 if f else 1.0 for f in v.fixed]
            joint.update(type="prismatic", axis=axis, line_point=joint["position"],
                         slide_distance=0.0)
        joints.append(joint)
    links: list[dict[str, Any]] = []
    ground_id = "ground"
    while ground_id in {b.id for b in lk.bars}:
        ground_id = f"_{ground_id}"
    if ground:
        links.append({"id": ground_id, "type": "ground", "joints": ground})
    links += [{"id": b.id, "type": "link", "joints": list(b.ends)} for b in lk.bars]
    data: dict[str, Any] = {"name": name, "joints": joints, "links": links}
    if ground:
        data["ground"] = ground_id
    return data


def to_pylinkage_mechanism(linkage: LinkageIn, name: str = "") -> Any:
    """A ``pylinkage.mechanism.Mechanism`` built by pylinkage from ``to_pylinkage``."""
    from pylinkage.mechanism import mechanism_from_dict

    return mechanism_from_dict(to_pylinkage(linkage, name))


def from_pylinkage(mechanism: Mapping[str, Any] | Any) -> Linkage:
    """A linkage from pylinkage's mechanism JSON (or a ``Mechanism``, serialised by pylinkage).

    Ground joints are pinned, prismatic joints with an axis along x or y are sliders; a link of
    two joints is a bar with the link's id, a link of k > 2 joints a rigid body braced by all
    its ``k (k - 1) / 2`` pairs (``link:a-b``); ground links add no bars (their ends are pinned).
    """
    if not isinstance(mechanism, Mapping):
        from pylinkage.mechanism import mechanism_to_dict

        mechanism = mechanism_to_dict(mechanism)
    grounded = {j for link in mechanism.get("links", []) if link.get("type") == "ground"
                for j in link.get("joints", [])}
    vertices = []
    for joint in mechanism.get("joints", []):
        kind = joint.get("type", "revolute")
        fixed: bool | tuple[bool, bool]
        if kind == "ground" or joint["id"] in grounded:
            fixed = True
        elif kind == "revolute":
            fixed = False
        elif kind == "prismatic":
            ax = np.asarray(joint.get("axis", [1.0, 0.0]), dtype=np.float64)
            if ax[1] == 0 and ax[0] != 0:
                fixed = (False, True)
            elif ax[0] == 0 and ax[1] != 0:
                fixed = (True, False)
            else:
                raise ValueError(f"prismatic joint {joint['id']!r} slides along {ax.tolist()}: "
                                 "only sliders along x or y are linkage vertices")
        else:
            raise ValueError(f"joint {joint['id']!r} is a {kind!r} joint: not a bar-and-joint "
                             "element")
        vertices.append(Vertex(str(joint["id"]), tuple(float(x) for x in joint["position"]),
                               fixed))
    bars: list[Bar] = []
    for link in mechanism.get("links", []):
        ends = [str(j) for j in link.get("joints", [])]
        if link.get("type") == "ground" or len(ends) < 2:
            continue
        if len(ends) == 2:
            bars.append(Bar(str(link["id"]), (ends[0], ends[1])))
        else:
            bars += [Bar(f"{link['id']}:{a}-{b}", (a, b)) for a, b in combinations(ends, 2)]
    return Linkage(tuple(vertices), tuple(bars), 2)


# ---------------------------------------------------------------- FOLD 1.1


def to_fold(linkage: LinkageIn, *, title: str | None = None) -> dict[str, Any]:
    """A FOLD 1.1 object (``json.dump`` it to a ``.fold`` file): frame class ``linkage``,
    ``vertices_coords``, ``edges_vertices`` and ``edges_length`` (every bar, no faces)."""
    lk = _linkage(linkage)
    index = {v.id: k for k, v in enumerate(lk.vertices)}
    lengths = lk.lengths()
    fold: dict[str, Any] = {
        "file_spec": FOLD_SPEC,
        "file_creator": "linkage_client",
        "file_classes": ["singleModel"],
        "frame_classes": ["linkage"],
        "frame_attributes": [f"{lk.dimension}D"],
        "frame_unit": "unit",
        "vertices_coords": [[float(x) for x in v.position] for v in lk.vertices],
        "edges_vertices": [[index[b.ends[0]], index[b.ends[1]]] for b in lk.bars],
        "edges_length": [lengths[b.id] for b in lk.bars],
        f"vertices_{FOLD_NS}:id": list(index),
        f"vertices_{FOLD_NS}:fixed": [v["fixed"] for v in linkage_json(lk)["vertices"]],
        f"edges_{FOLD_NS}:id": [b.id for b in lk.bars],
    }
    if title is not None:
        fold["file_title"] = title
    return fold


def _fold_dimension(fold: Mapping[str, Any], coords: list[list[float]]) -> int:
    attributes = fold.get("frame_attributes", [])
    if "2D" in attributes:
        return 2
    if "3D" in attributes:
        return 3
    widths = {len(c) for c in coords}
    if not widths <= {2, 3}:
        raise ValueError(f"vertices_coords of {sorted(widths)} coordinates: 2 or 3 are linkages")
    return max(widths, default=2)


def _fold_edges(fold: Mapping[str, Any], brace_faces: bool) -> list[tuple[int, int, str]]:
    """(u, v, default id) of every edge, and of the braces of each face when asked."""
    edges = [(int(u), int(v), f"e{k}") for k, (u, v) in enumerate(fold.get("edges_vertices", []))]
    if not edges and "faces_vertices" in fold:  # the edges are the faces' sides
        sides: dict[frozenset[int], tuple[int, int]] = {}
        for face in fold["faces_vertices"]:
            for a, b in zip(face, [*face[1:], face[0]], strict=True):
                sides.setdefault(frozenset((a, b)), (int(a), int(b)))
        edges = [(u, v, f"e{k}") for k, (u, v) in enumerate(sides.values())]
    if brace_faces:
        joined = {frozenset((u, v)) for u, v, _ in edges}
        for k, face in enumerate(fold.get("faces_vertices", [])):
            for a, b in combinations(dict.fromkeys(int(x) for x in face), 2):
                if frozenset((a, b)) not in joined:
                    joined.add(frozenset((a, b)))
                    edges.append((a, b, f"f{k}:{a}-{b}"))
    return edges


def from_fold(fold: Mapping[str, Any], *, brace_faces: bool = False) -> Linkage:
    """A linkage from a FOLD object's key frame: vertices from ``vertices_coords``, a bar for
    every edge of ``edges_vertices`` whatever its assignment (creases are bars), lengths from
    ``edges_length`` where given.

    ``brace_faces=True`` adds a bar between every two vertices of a face not yet joined, so that
    each face is rigid (a bar-and-joint model of rigid origami).
    """
    if "vertices_coords" not in fold:
        raise ValueError("the FOLD frame has no vertices_coords (abstract frames are not "
                         "linkages)")
    coords = [list(map(float, c)) for c in fold["vertices_coords"]]
    dimension = _fold_dimension(fold, coords)
    if any(any(c[dimension:]) for c in coords):
        raise ValueError(f"a {dimension}D frame has vertices with more coordinates")
    coords = [(c + [0.0] * dimension)[:dimension] for c in coords]
    ids = [str(i) for i in fold.get(f"vertices_{FOLD_NS}:id", [f"v{k}" for k in
                                                              range(len(coords))])]
    pins = fold.get(f"vertices_{FOLD_NS}:fixed", [False] * len(coords))
    edges = _fold_edges(fold, brace_faces)
    bar_ids = list(fold.get(f"edges_{FOLD_NS}:id", []))
    given = list(fold.get("edges_length", []))
    bars = []
    for k, (u, v, default) in enumerate(edges):
        if not (0 <= u < len(coords) and 0 <= v < len(coords)):
            raise ValueError(f"edge {k} joins vertex {u} and {v}: there are {len(coords)}")
        bars.append(Bar(str(bar_ids[k]) if k < len(bar_ids) else default, (ids[u], ids[v]),
                        float(given[k]) if k < len(given) and given[k] is not None else None))
    vertices = tuple(Vertex(ids[k], tuple(c), _fixed(pins[k], dimension))
                     for k, c in enumerate(coords))
    return Linkage(vertices, tuple(bars), dimension)
