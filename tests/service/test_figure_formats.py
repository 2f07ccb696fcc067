"""The figures' formats (service/figure_formats.py, and the TikZ and DXF writers
service/figure_tikz.py, service/figure_dxf.py): each format opened with a real reader (PNG
by its chunks and Pillow, PDF by pypdf, SVG as XML, TikZ compiled by pdflatex where one is
installed, DXF read back by ezdxf), asked for by the ``format`` field and by ``Accept``; the
negotiation's rules; the problems of formats not offered and of PNGs too large."""

from __future__ import annotations

import io
import math
import re
import shutil
import struct
import subprocess
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path
from typing import Any

import pytest

from engine.model.errors import InvalidRequest
from service.figure_formats import (
    MAX_PIXELS,
    MEDIA_TYPES,
    OCTET,
    OFFERED,
    NotAcceptable,
    check_pixels,
    negotiate,
)
from tests.service.test_figures import assert_problem, preset

SVG_NS = "{http://www.w3.org/2000/svg}"
#: The four-bar preset at L2 = 1.2: its bar lengths (the preset's parameters: a = L1 = L3 = 1).
LENGTHS = {"L1": 1.0, "L2": 1.2, "L3": 1.0}


def _tex_with_tikz() -> str | None:
    """pdflatex (or lualatex) where TikZ is installed too (.ci/run installs both), else None."""
    exe = shutil.which("pdflatex") or shutil.which("lualatex")
    kpsewhich = shutil.which("kpsewhich")
    if exe is None or kpsewhich is None:
        return None
    found = subprocess.run([kpsewhich, "tikz.sty"], capture_output=True, text=True, timeout=60)
    return exe if found.returncode == 0 and found.stdout.strip() else None


PDFLATEX = _tex_with_tikz()


@pytest.fixture(scope="module")
def four_bar(client: Any) -> dict[str, Any]:
    return preset(client, "four-bar", L2=1.2)


def draw(client: Any, path: str, body: dict[str, Any], accept: str | None = None) -> Any:
    headers = {} if accept is None else {"accept": accept}
    return client.post(f"/v1/figures/{path}", json=body, headers=headers)


def ok(response: Any, media_type: str) -> bytes:
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == media_type
    data: bytes = response.content
    return data


# -- readers written here (the formats' own specifications) ----------------------------------


def png_chunks(data: bytes) -> dict[str, bytes]:
    """The PNG's chunks by type, each CRC checked (PNG spec, 5.3)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    chunks, at = {}, 8
    while at < len(data):
        (n,) = struct.unpack(">I", data[at:at + 4])
        kind, body = data[at + 4:at + 8], data[at + 8:at + 8 + n]
        assert struct.unpack(">I", data[at + 8 + n:at + 12 + n])[0] == zlib.crc32(kind + body)
        chunks.setdefault(kind.decode("ascii"), body)
        at += 12 + n
    assert "IEND" in chunks
    return chunks


def png_size_and_dpi(data: bytes) -> tuple[int, int, float]:
    chunks = png_chunks(data)
    width, height = struct.unpack(">II", chunks["IHDR"][:8])
    per_metre_x, per_metre_y, unit = struct.unpack(">IIB", chunks["pHYs"])
    assert unit == 1 and per_metre_x == per_metre_y
    return width, height, per_metre_x * 0.0254


def svg_texts(data: bytes) -> list[str]:
    root = ET.fromstring(data)
    assert root.tag == f"{SVG_NS}svg"
    return ["".join(t.itertext()) for t in root.iter(f"{SVG_NS}text")]


def tikz_bars(text: str) -> dict[str, float]:
    """Each bar's drawn length, from the ``% bar-k ID`` comment and the ``\\draw`` after it."""
    found = re.findall(r"% bar-\d+ (\S+)\n\\draw\[[^\]]*\] \(([^)]*)\) -- \(([^)]*)\)", text)
    return {bar: math.dist(map(float, p.split(",")), map(float, q.split(",")))
            for bar, p, q in found}


def tikz_balanced(text: str) -> None:
    """One tikzpicture, braces balanced outside comments and escapes, every command ended."""
    lines = [re.sub(r"\\[{}%]", "", line).split("%")[0] for line in text.splitlines()]
    body = "\n".join(lines)
    depth = 0
    for ch in body:
        depth += {"{": 1, "}": -1}.get(ch, 0)
        assert depth >= 0
    assert depth == 0
    assert body.count("\\begin{tikzpicture}") == body.count("\\end{tikzpicture}") == 1
    commands = [ln for ln in lines if ln.startswith("\\") and "tikzpicture" not in ln]
    assert commands and all(ln.rstrip().endswith(";") for ln in commands)


def compile_tikz(text: bytes, tmp: Path) -> bytes:
    (tmp / "figure.tex").write_bytes(text)
    (tmp / "doc.tex").write_text("\\documentclass{article}\n\\usepackage{tikz}\n"
                                 "\\begin{document}\n\\input{figure.tex}\n\\end{document}\n")
    assert PDFLATEX is not None
    proc = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", "doc.tex"],
                          cwd=tmp, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]
    return (tmp / "doc.pdf").read_bytes()


# -- negotiation -----------------------------------------------------------------------------


@pytest.mark.parametrize(("accept", "fmt", "media_type"), [
    (None, "svg", "image/svg+xml"),
    ("*/*", "svg", "image/svg+xml"),
    ("image/*", "svg", "image/svg+xml"),
    ("image/png", "png", "image/png"),
    ("application/pdf", "pdf", "application/pdf"),
    ("text/x-tex", "tikz", "application/x-tex"),  # an alias
    ("application/dxf", "dxf", "image/vnd.dxf"),  # an alias
    ("image/svg+xml;q=0.2, image/png;q=0.9", "png", "image/png"),
    ("image/png;q=0, */*", "svg", "image/svg+xml"),  # the specific q=0 wins over */*
    ("image/svg+xml;q=0, image/*", "png", "image/png"),
    ("image/gif, application/pdf;q=0.1", "pdf", "application/pdf"),
    ("application/octet-stream", "svg", OCTET),
    ("IMAGE/PNG ; q=1.0", "png", "image/png"),
])
def test_accept_picks_the_format(accept: str | None, fmt: str, media_type: str) -> None:
    choice = negotiate("linkage", None, accept)
    assert (choice.format, choice.media_type) == (fmt, media_type)


def test_accept_names_only_what_the_figure_offers() -> None:
    # the configuration space has no DXF: the header's other choice is taken
    assert negotiate("configuration-space", None, "image/vnd.dxf, image/png;q=0.5").format == "png"
    for accept in ("application/json", "image/gif", "image/png;q=0", "image/*;q=x"):
        with pytest.raises(NotAcceptable, match=re.escape(repr(accept))):
            negotiate("linkage", None, accept)
    with pytest.raises(NotAcceptable, match="image/vnd.dxf"):
        negotiate("splitting", None, "image/vnd.dxf")


def test_the_format_field_and_the_header_must_agree() -> None:
    assert negotiate("linkage", "png", "image/*").media_type == "image/png"
    assert negotiate("linkage", "dxf", OCTET).media_type == OCTET
    assert negotiate("linkage", "pdf", "application/json, */*;q=0.1").format == "pdf"
    with pytest.raises(NotAcceptable, match="'png' is image/png"):
        negotiate("linkage", "png", "image/svg+xml")
    for figure, offered in OFFERED.items():
        for fmt in set(MEDIA_TYPES) - set(offered):
            with pytest.raises(InvalidRequest) as err:
                negotiate(figure, fmt, None)
            assert err.value.loc == ("format",) and fmt in err.value.message


def test_pixels_are_counted_before_drawing() -> None:
    assert check_pixels(6.4, 5.0, 100) == (640, 500)
    assert check_pixels(1.0, 1.0, 5000) == (5000, 5000)  # exactly at the limit
    assert 5000 * 5000 == MAX_PIXELS
    with pytest.raises(InvalidRequest) as err:
        check_pixels(1.0, 1.0, 5001)
    assert err.value.loc == ("dpi",)
    assert "25,000,000 pixels" in err.value.message and "at most 5000 dpi" in err.value.message


# -- each format through HTTP ------------------------------------------------------------------


@pytest.mark.parametrize("by", ["format", "accept"])
def test_svg_has_its_text_as_text(client: Any, four_bar: dict[str, Any], by: str) -> None:
    body = {"linkage": four_bar, **({"format": "svg"} if by == "format" else {})}
    data = ok(draw(client, "linkage", body, "image/svg+xml" if by == "accept" else None),
              "image/svg+xml")
    texts = svg_texts(data)
    for name in [*LENGTHS, "P1", "P2", "A", "B"]:  # every bar and vertex id, as a <text>
        assert name in texts
    assert b"DejaVuSans-" not in data  # no glyphs drawn as paths


@pytest.mark.parametrize("by", ["format", "accept"])
def test_png_has_the_pixels_of_its_dpi(client: Any, four_bar: dict[str, Any], by: str) -> None:
    sizes = {}
    for dpi in (50, 100):
        body = {"linkage": four_bar, "dpi": dpi, **({"format": "png"} if by == "format" else {})}
        data = ok(draw(client, "linkage", body, "image/png" if by == "accept" else None),
                  "image/png")
        width, height, dots = png_size_and_dpi(data)
        assert dots == pytest.approx(dpi, abs=0.02)
        sizes[dpi] = (width, height)
        from PIL import Image

        with Image.open(io.BytesIO(data)) as image:  # a second reader agrees
            image.load()
            assert image.size == (width, height)
    # twice the dpi: twice the pixels along each side (to the pixel matplotlib rounds)
    assert abs(sizes[100][0] - 2 * sizes[50][0]) <= 1
    assert abs(sizes[100][1] - 2 * sizes[50][1]) <= 1


def test_pdf_is_one_page_of_the_pngs_size(client: Any, four_bar: dict[str, Any]) -> None:
    from pypdf import PdfReader

    data = ok(draw(client, "linkage", {"linkage": four_bar}, "application/pdf"),
              "application/pdf")
    assert data.startswith(b"%PDF-1.")
    tail = data.rstrip()
    assert tail.endswith(b"%%EOF") and b"startxref" in tail[-64:] and b"trailer" in data
    reader = PdfReader(io.BytesIO(data), strict=True)
    assert len(reader.pages) == 1
    text = reader.pages[0].extract_text()
    assert all(name in text for name in LENGTHS)
    # the page is the figure's size: the PNG's pixels at 72 dpi (a PDF point is 1/72 in)
    png = ok(draw(client, "linkage", {"linkage": four_bar, "format": "png", "dpi": 72}),
             "image/png")
    width, height, _ = png_size_and_dpi(png)
    box = reader.pages[0].mediabox
    assert abs(float(box.width) - width) <= 1 and abs(float(box.height) - height) <= 1


@pytest.mark.parametrize("by", ["format", "accept"])
def test_dxf_has_the_bars_as_lines_of_their_lengths(client: Any, four_bar: dict[str, Any],
                                                     by: str) -> None:
    import ezdxf

    body = {"linkage": four_bar, "show": ["zero_modes"],
            **({"format": "dxf"} if by == "format" else {})}
    data = ok(draw(client, "linkage", body, "image/vnd.dxf" if by == "accept" else None),
              "image/vnd.dxf")
    doc = ezdxf.read(io.StringIO(data.decode("utf-8")))
    msp = doc.modelspace()
    bars = {}
    for line in msp.query("LINE[layer=='BARS']"):
        (tag,) = line.get_xdata("LINKAGE_TOPOLOGY")
        bars[tag.value.removeprefix("bar ")] = line.dxf.start.distance(line.dxf.end)
    assert bars.keys() == LENGTHS.keys()
    for bar, length in LENGTHS.items():
        assert bars[bar] == pytest.approx(length, abs=1e-9)
    points = {p.get_xdata("LINKAGE_TOPOLOGY")[0].value: p.dxf.layer for p in msp.query("POINT")}
    assert points == {"vertex P1": "PINS", "vertex P2": "PINS", "vertex A": "JOINTS",
                      "vertex B": "JOINTS"}
    assert len(msp.query("LINE[layer=='ZERO_MODE_0']")) == 2  # A and B move, the pins do not
    assert {t.dxf.text for t in msp.query("TEXT")} == {*LENGTHS, "P1", "P2", "A", "B"}


def test_dxf_keeps_a_3d_linkage_in_3d(client: Any) -> None:
    import ezdxf

    linkage = {"dimension": 3, "vertices": [
        {"id": "P", "position": [0, 0, 0], "fixed": True},
        {"id": "Q", "position": [2, 0, 0], "fixed": True},
        {"id": "A", "position": [1, 0, 1]}],
        "bars": [{"id": "a", "ends": ["P", "A"]}, {"id": "b", "ends": ["Q", "A"]}]}
    data = ok(draw(client, "linkage", {"linkage": linkage, "format": "dxf"}), "image/vnd.dxf")
    lines = ezdxf.read(io.StringIO(data.decode())).modelspace().query("LINE[layer=='BARS']")
    # sqrt(2) in 3D (their x-y projections are 1 long)
    assert [ln.dxf.start.distance(ln.dxf.end) for ln in lines] == pytest.approx(
        [math.sqrt(2)] * 2, abs=1e-12)


def test_a_slider_and_its_axis_are_in_the_dxf(client: Any) -> None:
    import ezdxf

    linkage = preset(client, "gated-kl-chain", n=4, gate=2)
    data = ok(draw(client, "linkage", {"linkage": linkage, "format": "dxf"}), "image/vnd.dxf")
    msp = ezdxf.read(io.StringIO(data.decode())).modelspace()
    assert len(msp.query("POINT[layer=='SLIDERS']")) == 1
    (axis,) = msp.query("LINE[layer=='SLIDER_AXES']")
    assert axis.dxf.linetype == "DASHED"
    assert len(msp.query("LINE[layer=='BARS']")) == len(linkage["bars"])


@pytest.mark.parametrize("by", ["format", "accept"])
def test_tikz_of_the_linkage(client: Any, four_bar: dict[str, Any], by: str,
                             tmp_path: Path) -> None:
    body = {"linkage": four_bar, "show": ["zero_modes"],
            **({"format": "tikz"} if by == "format" else {})}
    data = ok(draw(client, "linkage", body, "application/x-tex" if by == "accept" else None),
              "application/x-tex")
    text = data.decode("utf-8")
    tikz_balanced(text)
    drawn = tikz_bars(text)
    assert drawn.keys() == LENGTHS.keys()
    for bar, length in LENGTHS.items():  # 5 significant digits written
        assert drawn[bar] == pytest.approx(length, rel=1e-4)
    assert len(re.findall(r"^% pin-\d+$", text, re.M)) == 2
    assert len(re.findall(r"^% vertex-\d+$", text, re.M)) == 2
    assert text.count("% zero-mode-0") == 1
    if PDFLATEX is not None:
        compile_tikz(data, tmp_path)


def test_tikz_of_the_equilateral_four_bars_configuration_space(client: Any,
                                                               tmp_path: Path) -> None:
    data = ok(draw(client, "configuration-space", {"linkage": preset(client, "four-bar"),
                                                   "format": "tikz"}), "application/x-tex")
    text = data.decode("utf-8")
    tikz_balanced(text)
    # the paper's three branch points, each marked (Fig. 1)
    assert len(re.findall(r"^% critical-branch-\d+$", text, re.M)) == 3
    assert re.search(r"^% component-0-0 ", text, re.M)
    coords = [tuple(map(float, c.split(","))) for c in re.findall(
        r"\(([-\d.e]+,[-\d.e]+)\)", "".join(re.findall(r"plot coordinates \{([^}]*)\}", text)))]
    assert coords and all(abs(x) <= math.pi + 1e-4 and abs(y) <= math.pi + 1e-4
                          for x, y in coords)  # on the torus cut open
    if PDFLATEX is None:
        pytest.skip("no pdflatex or lualatex here: the TikZ's structure is checked, not compiled")
    from pypdf import PdfReader

    assert len(PdfReader(io.BytesIO(compile_tikz(data, tmp_path))).pages) == 1


def test_tikz_ids_are_escaped_for_tex(client: Any, tmp_path: Path) -> None:
    linkage = {"vertices": [{"id": "P_1", "position": [0, 0], "fixed": True},
                            {"id": "A&B", "position": [1, 0]},
                            {"id": "Q%", "position": [2, 0], "fixed": True}],
               "bars": [{"id": "r_{1}", "ends": ["P_1", "A&B"]},
                        {"id": "s#$~^\\", "ends": ["A&B", "Q%"]}]}
    data = ok(draw(client, "linkage", {"linkage": linkage, "format": "tikz"}),
              "application/x-tex")
    tikz_balanced(data.decode())
    if PDFLATEX is not None:
        compile_tikz(data, tmp_path)


def test_the_other_figures_in_png_and_pdf(client: Any, four_bar: dict[str, Any]) -> None:
    from pypdf import PdfReader

    body = {"linkage": four_bar, "perturbation": {"L2": 0.01}}
    png = ok(draw(client, "splitting", {**body, "format": "png", "dpi": 40}), "image/png")
    assert png_size_and_dpi(png)[2] == pytest.approx(40, abs=0.02)
    pdf = ok(draw(client, "splitting", body, "application/pdf"), "application/pdf")
    assert len(PdfReader(io.BytesIO(pdf)).pages) == 1
    space = {"linkage": four_bar, "options": {"max_points": 2000}}
    pdf = ok(draw(client, "configuration-space", space, "application/pdf"), "application/pdf")
    assert len(PdfReader(io.BytesIO(pdf)).pages) == 1


@pytest.mark.slow
def test_critical_values_in_png(client: Any, four_bar: dict[str, Any]) -> None:
    body = {"linkage": four_bar, "format": "png", "dpi": 60,
            "axes": [{"bar": "L2", "min": 0.4, "max": 2.5}, {"bar": "L3", "min": 0.4, "max": 2.5}],
            "options": {"resolution": 12, "seeds_per_axis": 2}}
    width, height, dots = png_size_and_dpi(ok(draw(client, "critical-values", body), "image/png"))
    assert dots == pytest.approx(60, abs=0.02) and width > 0 and height > 0


def test_octet_stream_answers_the_bytes_of_the_format(client: Any,
                                                      four_bar: dict[str, Any]) -> None:
    r = draw(client, "linkage", {"linkage": four_bar, "format": "png", "dpi": 30}, OCTET)
    png_chunks(ok(r, OCTET))
    assert r.headers["content-disposition"] == 'inline; filename="linkage.png"'
    assert "accept" in r.headers["vary"].lower()
    svg_texts(ok(draw(client, "linkage", {"linkage": four_bar}, OCTET), OCTET))


# -- problems ------------------------------------------------------------------------------


def test_unsupported_formats_are_problems_naming_them(client: Any,
                                                      four_bar: dict[str, Any]) -> None:
    r = draw(client, "linkage", {"linkage": four_bar, "format": "gif"})
    assert_problem(r, 422, ["body", "format"])
    r = draw(client, "splitting", {"linkage": four_bar, "perturbation": {"L2": 0.01},
                                   "format": "tikz"})
    assert_problem(r, 422, ["body", "format"])
    assert "tikz" in r.json()["detail"]
    r = draw(client, "critical-values", {
        "linkage": four_bar, "format": "dxf",
        "axes": [{"bar": "L2", "min": 0.5, "max": 1.5}, {"bar": "L3", "min": 0.5, "max": 1.5}]})
    assert_problem(r, 422, ["body", "format"])
    r = draw(client, "linkage", {"linkage": four_bar}, "image/gif")
    assert_problem(r, 406, ["header", "accept"])
    assert "image/gif" in r.json()["detail"]
    r = draw(client, "configuration-space", {"linkage": four_bar}, "image/vnd.dxf")
    assert_problem(r, 406, ["header", "accept"])
    r = draw(client, "linkage", {"linkage": four_bar, "format": "png"}, "image/svg+xml")
    assert_problem(r, 406, ["header", "accept"])
    assert "png" in r.json()["detail"]
    assert client.get("/health").status_code == 200


def test_a_png_too_large_is_refused_naming_the_limit(client: Any,
                                                      four_bar: dict[str, Any]) -> None:
    r = draw(client, "linkage", {"linkage": four_bar, "format": "png", "dpi": 100_000})
    assert_problem(r, 422, ["body", "dpi"])
    assert "1200" in r.json()["detail"]
    # within the schema's bounds, but over MAX_PIXELS at the figure's size: refused before
    # the analysis runs (the configuration space is never searched)
    for path, body in (("linkage", {"linkage": four_bar}),
                       ("configuration-space", {"linkage": four_bar})):
        r = draw(client, path, {**body, "format": "png", "dpi": 1200})
        assert_problem(r, 422, ["body", "dpi"])
        assert f"{MAX_PIXELS:,} pixels" in r.json()["detail"]
    r = draw(client, "linkage", {"linkage": four_bar, "dpi": 1200}, "image/png")
    assert_problem(r, 422, ["body", "dpi"])
    # the same dpi is no problem for a vector format
    ok(draw(client, "linkage", {"linkage": four_bar, "dpi": 1200}, "application/pdf"),
       "application/pdf")
    assert client.get("/health").status_code == 200


def test_the_drawn_size_is_checked_before_rasterising() -> None:
    """A figure whose own size (known only once drawn) is over the limit: the check of the
    drawn figure, in the worker, before any pixel is allocated."""
    from matplotlib.figure import Figure

    from service.figures import _render
    from service.schemas.figures import LinkageFigureRequest

    body = LinkageFigureRequest.model_validate(
        {"linkage": {"vertices": [{"id": "A", "position": [0, 0]}], "bars": []},
         "format": "png", "dpi": 1000})
    with pytest.raises(InvalidRequest) as err:
        _render(body, lambda: Figure(figsize=(8.0, 8.0)))  # 8000 x 8000 px
    assert err.value.loc == ("dpi",) and "64,000,000" in err.value.message
    assert _render(body.model_copy(update={"dpi": 100}),
                   lambda: Figure(figsize=(8.0, 8.0))).startswith(b"\x89PNG")


# -- the OpenAPI contract and a generated client ---------------------------------------------


def test_openapi_lists_every_offered_media_type(app: Any) -> None:
    spec = app.openapi()
    for figure, offered in OFFERED.items():
        op = spec["paths"][f"/v1/figures/{figure}"]["post"]
        content = op["responses"]["200"]["content"]
        assert list(content) == [MEDIA_TYPES[f] for f in offered] + [OCTET]
        assert "406" in op["responses"] and "422" in op["responses"]
        schema = op["requestBody"]["content"]["application/json"]["schema"]["$ref"]
        props = spec["components"]["schemas"][schema.rsplit("/", 1)[1]]["properties"]
        assert {"format", "dpi"} <= props.keys()


@pytest.mark.slow
def test_a_generated_client_reads_the_figures(app: Any, tmp_path: Path,
                                              four_bar: dict[str, Any]) -> None:
    """openapi-python-client (the generator the issue named) on openapi/openapi.json: the
    figure operations' 200s are files of bytes (before, image/svg+xml alone was an unknown
    media type and the answer was dropped: ``parsed`` was None)."""
    import asyncio
    import importlib
    import sys

    import httpx

    root = Path(__file__).resolve().parents[2]
    (tmp_path / "config.yaml").write_text("post_hooks: []\n")
    generator = Path(sys.executable).with_name("openapi-python-client")
    proc = subprocess.run([str(generator), "generate", "--path",
                           str(root / "openapi" / "openapi.json"), "--meta", "none",
                           "--config", str(tmp_path / "config.yaml"), "--output-path",
                           str(tmp_path / "generated_linkage")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for path in OFFERED:
        assert f"POST /v1/figures/{path}" not in proc.stdout, proc.stdout
    sys.path.insert(0, str(tmp_path))
    try:
        generated = importlib.import_module("generated_linkage")
        draw_linkage = importlib.import_module("generated_linkage.api.figures.draw_linkage")
        models = importlib.import_module("generated_linkage.models")
        api = generated.Client(base_url="http://testserver")
        api.set_async_httpx_client(httpx.AsyncClient(transport=httpx.ASGITransport(app=app),
                                                     base_url="http://testserver"))

        async def fetch(body: dict[str, Any]) -> Any:
            return await draw_linkage.asyncio_detailed(
                client=api, body=models.LinkageFigureRequest.from_dict(body))

        png = asyncio.run(fetch({"linkage": four_bar, "format": "png", "dpi": 30}))
        assert png.status_code == 200 and png_chunks(png.parsed.payload.read())
        pdf = asyncio.run(fetch({"linkage": four_bar, "format": "pdf"}))
        assert pdf.parsed.payload.read().startswith(b"%PDF-")
    finally:
        sys.path.remove(str(tmp_path))
        for name in [m for m in sys.modules if m.startswith("generated_linkage")]:
            del sys.modules[name]
