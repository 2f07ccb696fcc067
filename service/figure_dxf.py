"""DXF of a linkage's geometry for CAD, written with ezdxf (DXF R2010, UTF-8 text).

The linkage at the answer's configuration, in its own coordinates and units (``$INSUNITS`` 0:
unitless), 3D linkages in 3D: each bar a ``LINE`` on layer ``BARS`` whose extended data
(application ``LINKAGE_TOPOLOGY``) names the bar, each joint a ``POINT`` (the exact position)
and a ``CIRCLE`` around it on layer ``PINS``, ``SLIDERS`` or ``JOINTS``, a slider's axis a
dashed ``LINE`` on ``SLIDER_AXES``, the ids as ``TEXT`` on ``LABELS``; zero modes or branch
tangents, when asked for, as ``LINE`` arrows' shafts on ``ZERO_MODE_<j>`` / ``TANGENT_<j>``
(the self-stress is a colour of the SVG, not geometry: not written).
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import ezdxf
import numpy as np

from service.figure_drawing import _bar_length, _fixed_axes
from service.schemas import common as c

#: The application name of the extended data that carries each entity's id.
APPID = "LINKAGE_TOPOLOGY"
#: Layers and their ACI colours (7: black/white, 1: red, 6: magenta, 8: grey, 3: green).
LAYERS = {"BARS": 7, "PINS": 1, "SLIDERS": 6, "JOINTS": 7, "SLIDER_AXES": 6, "LABELS": 8}


def _tag(entity: object, what: str) -> None:
    entity.set_xdata(APPID, [(1000, what)])  # type: ignore[attr-defined]


def linkage(lk: c.Linkage, ans: object, show: Sequence[str]) -> bytes:
    """The linkage at the answer's configuration as a DXF document (its bytes)."""
    conf: dict[str, list[float]] = ans.configuration  # type: ignore[attr-defined]
    ids = [v.id for v in lk.vertices]
    pos = np.zeros((len(ids), 3))  # (V, 3): z = 0 in the plane
    pos[:, : lk.dimension] = np.array([conf[i] for i in ids], dtype=float).reshape(len(ids), -1)
    index = {vid: k for k, vid in enumerate(ids)}
    lengths = [_bar_length(lk, b) for b in lk.bars]
    scale = float(np.median(lengths)) if lengths else 1.0
    doc = ezdxf.new("R2010", setup=["linetypes"])
    doc.header["$INSUNITS"] = 0
    doc.appids.add(APPID)
    for name, colour in LAYERS.items():
        doc.layers.add(name, color=colour)
    msp = doc.modelspace()
    text_height = 0.06 * scale
    for bar in lk.bars:
        p, q = pos[index[bar.ends[0]]], pos[index[bar.ends[1]]]
        _tag(msp.add_line(tuple(p), tuple(q), dxfattribs={"layer": "BARS"}), f"bar {bar.id}")
        msp.add_text(bar.id, height=text_height, dxfattribs={"layer": "LABELS"}).set_placement(
            tuple((p + q) / 2))
    for k, v in enumerate(lk.vertices):
        mask = _fixed_axes(v, lk.dimension)
        layer = "PINS" if all(mask) else "SLIDERS" if any(mask) else "JOINTS"
        _tag(msp.add_point(tuple(pos[k]), dxfattribs={"layer": layer}), f"vertex {v.id}")
        msp.add_circle(tuple(pos[k]), radius=0.04 * scale, dxfattribs={"layer": layer})
        if layer == "SLIDERS":
            free = np.array([0.0 if f else 1.0 for f in mask] + [0.0] * (3 - len(mask)))
            if free.any():
                axis = msp.add_line(tuple(pos[k] - free * scale), tuple(pos[k] + free * scale),
                                    dxfattribs={"layer": "SLIDER_AXES", "linetype": "DASHED"})
                _tag(axis, f"slider axis {v.id}")
        msp.add_text(v.id, height=text_height, dxfattribs={"layer": "LABELS"}).set_placement(
            tuple(pos[k] - [1.5 * text_height, 1.5 * text_height, 0.0]))
    arrows: list[tuple[str, list[dict[str, list[float]]]]] = []
    if "zero_modes" in show:
        arrows.append(("ZERO_MODE", list(ans.zero_modes)))  # type: ignore[attr-defined]
    if "tangents" in show:
        arrows.append(("TANGENT", list(getattr(ans, "tangents", []))))
    for prefix, vectors in arrows:
        for j, vec in enumerate(vectors):
            arr = np.zeros_like(pos)
            arr[:, : lk.dimension] = np.array([vec[i] for i in ids]).reshape(len(ids), -1)
            arr *= 0.4 * scale / (float(np.max(np.linalg.norm(arr, axis=1))) or 1.0)
            layer = f"{prefix}_{j}"
            doc.layers.add(layer, color=3)
            for p, d in zip(pos, arr, strict=True):
                if np.linalg.norm(d) > 1e-12:
                    msp.add_line(tuple(p), tuple(p + d), dxfattribs={"layer": layer})
    out = io.StringIO()
    doc.write(out)
    return out.getvalue().encode("utf-8")
