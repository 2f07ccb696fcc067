"""Interchange round trips through the real libraries (PyRigi, networkx, pylinkage) and FOLD
1.1 (read back by a reader written here from the spec's field names), on every catalogue
preset and on random linkages: same graph, same positions, same lengths."""

from __future__ import annotations

import json
import math
import string
from collections.abc import Iterator
from typing import Any

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from linkage_client import Client, Linkage
from linkage_client import formats as F
from pylinkage.mechanism import Mechanism, mechanism_from_dict, mechanism_to_dict
from pyrigi import Framework

RTOL = 1e-12


@pytest.fixture(scope="module")
def presets(sync: Client) -> dict[str, Linkage]:
    """Every catalogue linkage with its defaults, fetched through GET /v1/presets/{name}."""
    return {p.name: sync.get_preset(p.name) for p in sync.list_presets()}


def random_linkage(seed: int) -> Linkage:
    """A connected random linkage: 2D or 3D, pins, sliders (2D), some lengths given."""
    rng = np.random.default_rng(seed)
    d = int(rng.choice([2, 3]))
    n = int(rng.integers(2, 10))
    pos = rng.normal(scale=2.0, size=(n, d))
    pairs = {frozenset((k, int(rng.integers(0, k)))) for k in range(1, n)}  # a spanning tree
    for _ in range(int(rng.integers(0, n))):
        a, b = rng.choice(n, size=2, replace=False)
        pairs.add(frozenset((int(a), int(b))))
    kinds: list[Any] = [False, True] + ([[True, False], [False, True]] if d == 2 else [])
    vertices = [{"id": f"v{k}", "position": pos[k].tolist(),
                 "fixed": kinds[int(rng.integers(0, len(kinds)))]} for k in range(n)]
    bars = []
    for j, pair in enumerate(sorted(tuple(sorted(p)) for p in pairs)):
        bar: dict[str, Any] = {"id": f"b{j}", "ends": [f"v{pair[0]}", f"v{pair[1]}"]}
        if rng.random() < 0.5:  # given, equal to the ends' distance as float64 computes it
            bar["length"] = float(np.linalg.norm(pos[pair[0]] - pos[pair[1]]))
        bars.append(bar)
    return Linkage.from_json({"dimension": d, "vertices": vertices, "bars": bars})


RANDOM = [random_linkage(seed) for seed in range(25)]


def every(presets: dict[str, Linkage]) -> Iterator[tuple[str, Linkage]]:
    yield from presets.items()
    yield from ((f"random-{k}", lk) for k, lk in enumerate(RANDOM))


def edges(lk: Linkage) -> dict[str, frozenset[str]]:
    return {b.id: frozenset(b.ends) for b in lk.bars}


def assert_same(a: Linkage, b: Linkage, *, ids: bool = True, pins: bool = True) -> None:
    """Same graph, same positions (to the bit), same lengths (to rounding)."""
    assert a.dimension == b.dimension
    assert a.vertex_ids == b.vertex_ids
    assert np.array_equal(a.positions.array, b.positions.array)
    if pins:
        assert a.fixed_axes().tolist() == b.fixed_axes().tolist()
    if ids:
        assert edges(a) == edges(b)
        la, lb = a.lengths(), b.lengths()
        assert all(math.isclose(la[k], lb[k], rel_tol=RTOL) for k in la)
    else:
        assert sorted(map(sorted, edges(a).values())) == sorted(map(sorted, edges(b).values()))


def distance(p: Any, q: Any) -> float:
    return float(np.linalg.norm(np.asarray(p, dtype=float) - np.asarray(q, dtype=float)))


# ---------------------------------------------------------------- networkx


def test_networkx_round_trip(presets: dict[str, Linkage]) -> None:
    for name, lk in every(presets):
        graph = F.to_networkx(lk)
        assert isinstance(graph, nx.Graph) and not graph.is_multigraph(), name
        assert set(graph.nodes) == set(lk.vertex_ids)
        assert {frozenset(e) for e in graph.edges} == set(edges(lk).values())
        pos = nx.get_node_attributes(graph, "pos")  # what networkx.draw takes
        assert all(pos[v.id] == tuple(v.position) for v in lk.vertices)
        lengths = lk.lengths()
        for _, _, data in graph.edges(data=True):  # networkx's own view of the bars
            assert data["length"] == lengths[data["id"]]
        back = F.from_networkx(graph)
        assert_same(lk, back)
        # through networkx's own node-link JSON and back
        again = F.from_networkx(nx.node_link_graph(nx.node_link_data(graph, edges="links"),
                                                   edges="links"))
        assert_same(lk, again)


def test_networkx_graph_without_attributes_takes_a_layout() -> None:
    graph = nx.cycle_graph(5)
    layout = nx.circular_layout(graph)
    lk = F.from_networkx(graph, layout)
    assert lk.vertex_ids == ("0", "1", "2", "3", "4") and len(lk.bars) == 5
    assert all(lk.positions[str(k)].tolist() == list(layout[k]) for k in graph.nodes)
    side = 2 * math.sin(math.pi / 5)  # the regular pentagon's side (networkx lays it out in
    assert all(math.isclose(x, side, rel_tol=1e-6) for x in lk.lengths().values())  # float32)
    with pytest.raises(ValueError, match="no position"):
        F.from_networkx(nx.path_graph(3))
    with pytest.raises(ValueError, match="simple"):
        F.from_networkx(nx.MultiGraph([(0, 1), (0, 1)]), {0: (0, 0), 1: (1, 0)})


# ---------------------------------------------------------------- PyRigi


def test_pyrigi_round_trip(presets: dict[str, Linkage]) -> None:
    for name, lk in every(presets):
        framework = F.to_pyrigi(lk)
        assert isinstance(framework, Framework), name
        assert framework.dim == lk.dimension
        realization = framework.realization(as_points=True, numerical=True)
        assert all(list(realization[v.id]) == list(v.position) for v in lk.vertices)
        lengths = lk.lengths()
        pyrigi_lengths = framework.edge_lengths(numerical=True)  # PyRigi's own computation
        assert len(pyrigi_lengths) == len(lk.bars)
        for bar in lk.bars:
            key = bar.ends if bar.ends in pyrigi_lengths else bar.ends[::-1]
            assert math.isclose(pyrigi_lengths[key], lengths[bar.id], rel_tol=1e-9), name
        assert_same(lk, F.from_pyrigi(framework))


def test_pyrigi_framework_made_by_pyrigi() -> None:
    framework = Framework.Complete([(0, 0), (3, 0), (0, 4)])
    lk = F.from_pyrigi(framework, fixed={0: True})
    assert lk.vertex_ids == ("0", "1", "2") and lk.fixed_axes()[:, 0].tolist() == [1, 0, 0]
    assert sorted(lk.lengths().values()) == [3.0, 4.0, 5.0]
    assert F.to_pyrigi(lk).is_inf_rigid()  # a triangle, as PyRigi sees it


def test_pyrigi_refuses_what_a_framework_cannot_hold() -> None:
    lk = RANDOM[0].to_json()
    lk["bars"][0]["length"] = 123.0
    with pytest.raises(ValueError, match="keeps positions only"):
        F.to_pyrigi(lk)
    lk = RANDOM[0].to_json()
    lk["bars"].append({"id": "twin", "ends": lk["bars"][0]["ends"]})
    with pytest.raises(ValueError, match="same vertices"):
        F.to_pyrigi(lk)


# ---------------------------------------------------------------- pylinkage


def pylinkage_lengths(mechanism: Mechanism) -> dict[str, float]:
    """Each binary link's length from pylinkage's own joint objects."""
    return {link.id: distance(link.joints[0].position, link.joints[1].position)
            for link in mechanism.links if len(link.joints) == 2
            and type(link).__name__ != "GroundLink"}


def test_pylinkage_round_trip(presets: dict[str, Linkage]) -> None:
    for name, lk in every(presets):
        if lk.dimension != 2:
            with pytest.raises(ValueError, match="planar"):
                F.to_pylinkage(lk)
            continue
        mechanism = mechanism_from_dict(json.loads(json.dumps(F.to_pylinkage(lk, name))))
        assert isinstance(mechanism, Mechanism)
        joints = {j.id: j for j in mechanism.joints}
        assert list(joints) == list(lk.vertex_ids), name
        for v in lk.vertices:
            assert tuple(joints[v.id].position) == tuple(v.position)
            axes = lk.fixed_axes()[lk.vertex_ids.index(v.id)]
            expected = ("GroundJoint" if axes.all() else "RevoluteJoint" if not axes.any()
                        else "PrismaticJoint")
            assert type(joints[v.id]).__name__ == expected, (name, v)
        lengths = lk.lengths()
        assert {k: pytest.approx(x, rel=1e-9) for k, x in lengths.items()} \
            == pylinkage_lengths(mechanism)
        back = F.from_pylinkage(mechanism)  # serialised by pylinkage's mechanism_to_dict
        assert_same(lk, back)
        assert F.from_pylinkage(mechanism_to_dict(mechanism)) == back


def test_pylinkage_rigid_body_links_are_braced() -> None:
    data = {"name": "tri", "joints": [
        {"id": "O", "type": "ground", "position": [0.0, 0.0]},
        {"id": "A", "type": "revolute", "position": [1.0, 0.0]},
        {"id": "B", "type": "revolute", "position": [1.0, 1.0]},
        {"id": "C", "type": "revolute", "position": [2.0, 0.5]}],
        "links": [{"id": "crank", "type": "driver", "joints": ["O", "A"], "motor_joint": "O"},
                  {"id": "plate", "type": "link", "joints": ["A", "B", "C"]}]}
    lk = F.from_pylinkage(mechanism_to_dict(mechanism_from_dict(data)))
    assert edges(lk) == {"crank": {"O", "A"}, "plate:A-B": {"A", "B"},
                         "plate:A-C": {"A", "C"}, "plate:B-C": {"B", "C"}}
    assert lk.fixed_axes()[0].all() and not lk.fixed_axes()[1:].any()


# ---------------------------------------------------------------- FOLD 1.1

#: The FOLD spec's (version 1.1) property names of a key frame (doc/spec.md of edemaine/fold).
FOLD_FILE = {"file_spec", "file_creator", "file_author", "file_title", "file_description",
             "file_classes", "file_frames"}
FOLD_FRAME = {"frame_author", "frame_title", "frame_description", "frame_classes",
              "frame_attributes", "frame_unit", "vertices_coords", "vertices_vertices",
              "vertices_edges", "vertices_faces", "edges_vertices", "edges_faces",
              "edges_assignment", "edges_foldAngle", "edges_length", "faces_vertices",
              "faces_edges", "faces_faces", "faceOrders", "edgeOrders"}
FOLD_ASSIGNMENTS_1_1 = {"B", "M", "V", "F", "U"}


def read_fold(text: str) -> tuple[list[list[float]], list[tuple[int, int]], list[float] | None]:
    """A reference reader: checks a FOLD 1.1 key frame against the spec and gives its vertex
    coordinates, its edges and their lengths (standard fields only)."""
    fold = json.loads(text)
    assert isinstance(fold, dict)
    for key in fold:  # unknown names must be custom (a colon: "Custom Properties")
        assert key in FOLD_FILE | FOLD_FRAME or ":" in key, key
    assert fold["file_spec"] == 1.1
    for key in ("file_classes", "frame_classes", "frame_attributes"):
        values = fold.get(key, [])
        assert isinstance(values, list) and all(isinstance(v, str) for v in values)
    coords = fold["vertices_coords"]
    assert all(isinstance(c, list) and len(c) in (2, 3)
               and all(isinstance(x, (int, float)) for x in c) for c in coords)
    pairs = [tuple(e) for e in fold.get("edges_vertices", [])]
    assert all(len(e) == 2 and all(isinstance(i, int) and 0 <= i < len(coords) for i in e)
               for e in pairs)
    for key, value in fold.items():  # parallel arrays: one entry per vertex, per edge
        prefix = key.split("_", 1)[0]
        if prefix == "vertices":
            assert len(value) == len(coords), key
        elif prefix == "edges":
            assert len(value) == len(pairs), key
    assert set(fold.get("edges_assignment", [])) <= FOLD_ASSIGNMENTS_1_1
    if "linkage" in fold.get("frame_classes", []):  # "vertices and edges and edge lengths"
        assert "edges_length" in fold and "faces_vertices" not in fold
    if "2D" in fold.get("frame_attributes", []):
        assert all(len(c) == 2 or c[2] == 0 for c in coords)
    return coords, pairs, fold.get("edges_length")


def test_fold_round_trip_read_by_the_reference_reader(presets: dict[str, Linkage]) -> None:
    for name, lk in every(presets):
        text = json.dumps(F.to_fold(lk, title=name))
        coords, pairs, lengths = read_fold(text)
        index = {v: k for k, v in enumerate(lk.vertex_ids)}
        assert coords == [list(v.position) for v in lk.vertices], name
        assert pairs == [(index[b.ends[0]], index[b.ends[1]]) for b in lk.bars]
        assert lengths == [lk.lengths()[b.id] for b in lk.bars]
        assert_same(lk, F.from_fold(json.loads(text)))


def test_fold_crease_pattern_without_our_fields() -> None:
    """A square folded along a diagonal, as FOLD writers give it (faces, assignments)."""
    fold = {"file_spec": 1.1, "frame_classes": ["creasePattern"],
            "vertices_coords": [[0, 0], [1, 0], [1, 1], [0, 1]],
            "edges_vertices": [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]],
            "edges_assignment": ["B", "B", "B", "B", "V"],
            "faces_vertices": [[0, 1, 2], [0, 2, 3]]}
    read_fold(json.dumps(fold))
    lk = F.from_fold(fold)
    assert lk.dimension == 2 and lk.vertex_ids == ("v0", "v1", "v2", "v3")
    assert edges(lk)["e4"] == {"v0", "v2"} and len(lk.bars) == 5  # the crease is a bar
    assert math.isclose(lk.lengths()["e4"], math.sqrt(2))
    quad = {"vertices_coords": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
            "faces_vertices": [[0, 1, 2, 3]]}
    assert len(F.from_fold(quad).bars) == 4  # the sides of the face
    braced = F.from_fold(quad, brace_faces=True)
    assert len(braced.bars) == 6 and braced.dimension == 3
    with pytest.raises(ValueError, match="abstract"):
        F.from_fold({"edges_vertices": [[0, 1]], "edges_length": [1.0]})


# ---------------------------------------------------------------- property: any linkage

IDS = st.text(alphabet=string.ascii_letters + string.digits + "-_:.", min_size=1, max_size=6)


@st.composite
def linkages(draw: st.DrawFn) -> Linkage:
    """Connected linkages with arbitrary ids, coordinates, pins and sliders (2D), and lengths
    given or not."""
    d = draw(st.sampled_from([2, 3]))
    n = draw(st.integers(2, 8))
    ids = draw(st.lists(IDS, min_size=n, max_size=n, unique=True))
    coord = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
    pos = [draw(st.lists(coord, min_size=d, max_size=d)) for _ in range(n)]
    pairs = {frozenset((k, draw(st.integers(0, k - 1)))) for k in range(1, n)}
    extra = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)),
                          max_size=n))
    pairs |= {frozenset(p) for p in extra if p[0] != p[1]}
    kinds: list[Any] = [False, True] + ([[True, False], [False, True]] if d == 2 else [])
    vertices = [{"id": ids[k], "position": pos[k], "fixed": draw(st.sampled_from(kinds))}
                for k in range(n)]
    bars = []
    for j, pair in enumerate(sorted(tuple(sorted(p)) for p in pairs)):
        bar: dict[str, Any] = {"id": f"b{j}", "ends": [ids[pair[0]], ids[pair[1]]]}
        if draw(st.booleans()):
            bar["length"] = distance(pos[pair[0]], pos[pair[1]])
        bars.append(bar)
    return Linkage.from_json({"dimension": d, "vertices": vertices, "bars": bars})


@settings(max_examples=60, deadline=None)
@given(linkages())
def test_every_format_round_trips_any_linkage(lk: Linkage) -> None:
    assert_same(lk, F.from_networkx(F.to_networkx(lk)))
    assert_same(lk, F.from_pyrigi(F.to_pyrigi(lk)))
    assert_same(lk, F.from_fold(json.loads(json.dumps(F.to_fold(lk)))))
    if lk.dimension == 2:
        mechanism = mechanism_from_dict(F.to_pylinkage(lk))
        assert_same(lk, F.from_pylinkage(mechanism))
