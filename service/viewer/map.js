// The map panel: the critical values in the lengths of two bars (/v1/analysis/critical-values),
// each region labelled as the service labels it (its number of components and whatever else the
// answer gives a region, e.g. tau signs or gated), the robustness margin in those two lengths
// (/v1/analysis/robustness) drawn around the linkage's point, and a click on a region loads the
// linkage at the region's sample lengths.
"use strict";

// the fields of a region shown by their own rules (the rest as given, by name)
const REGION_BASE = new Set(["point", "components", "signature", "cells", "argument",
  "components_exact", "components_traced", "components_rule", "gated_reason"]);
// shades of gated and ungated regions' markers (the paper's Fig. 5b: blue gated, red ungated)
const GATED_FILL = { true: "#cfe3f5", false: "#f6d0d8" };
const mapView = { answer: null, margin: null, frame: null, request: null };
const QUICK_S = 0.4; // seconds the margin's search may take while a drag goes on
// The map asked while a drag goes on: a coarser raster, fewer seed lengths and no homotopy sweep
// of the box's edges (the curves traced from the seeds only), which the service answers in
// 0.02-0.3 s for the catalogue's small linkages (the full map: 0.05 s to 4 s and more). It is
// drawn as provisional (dashed) and always replaced by the full map once the hand rests.
const QUICK_MAP = { resolution: 12, seeds_per_axis: 2, homotopy_paths_max: 0,
                    time_budget_s: 0.8 };

function mapAxesChoice(linkage) {
  // Bars that can change length: not both ends pinned.
  const pins = new Set(linkage.vertices.filter((v) => pinned(v, linkage.dimension || 2))
                                      .map((v) => v.id));
  const bars = linkage.bars.filter((b) => !(pins.has(b.ends[0]) && pins.has(b.ends[1])));
  for (const [id, pick] of [["axis-x", 1], ["axis-y", 2]]) {
    const sel = $(id);
    const keep = sel.value;
    sel.replaceChildren(...bars.map((b) => new Option(b.id, b.id)));
    if (bars.some((b) => b.id === keep)) sel.value = keep;
    else if (bars.length) sel.value = bars[Math.min(pick, bars.length - 1)].id;
  }
}

/** The body of the map's request for the linkage shown (null without two different bars). */
function mapRequest() {
  const linkage = state.drawable ? state.linkage : null;
  const [x, y] = [$("axis-x").value, $("axis-y").value];
  if (!linkage || !x || !y || x === y) return null;
  const bars = Object.fromEntries(linkage.bars.map((b) => [b.id, b]));
  const factor = Math.max(1.1, Number($("axis-range").value) || 2.5);
  const axes = [x, y].map((id) => {
    const len = barLength(linkage, bars[id]);
    return { bar: id, min: len / factor, max: len * factor };
  });
  return { linkage, axes };
}

/** A number as the viewer shows it (the tests read the same rounding). */
function fmt(x, digits = 4) {
  return typeof x === "number" ? Number(x.toPrecision(digits)).toString() : String(x);
}

/** Signs as the paper writes them: (+,+,-). */
function signsText(signs) {
  return `(${signs.map((x) => (x > 0 ? "+" : x < 0 ? "-" : "0")).join(",")})`;
}

/** A region's count as it is known: exact, exact beside fewer traced, or a lower bound. */
function countText(region) {
  const n = region.components;
  if (n === null || n === undefined) return "? (not explored in time)";
  const noun = `component${String(n) === "1" ? "" : "s"}`;
  if (region.components_exact === false) return `≥${n} ${noun} (a lower bound: traced)`;
  const traced = region.components_traced;
  return traced !== null && traced !== undefined && String(traced) !== String(n)
    ? `${n} ${noun} (${traced} traced)` : `${n} ${noun}`;
}

function regionLabel(region) {
  const parts = [countText(region)];
  for (const [k, v] of Object.entries(region)) {
    if (REGION_BASE.has(k)) continue;
    if (k === "gated" && v === null && region.gated_reason) {
      // (an empty region has nothing to gate: its count says so)
      if (String(region.components) !== "0") parts.push("gate undecided");
    } else if (v === null || v === undefined) {
      continue;
    } else if (k === "tau_signs") {
      const shown = v.slice(0, 3).map((c) => `τ ${c.cell} ${signsText(c.signs)}`);
      if (v.length > 3) shown.push(`+${v.length - 3} cells`);
      parts.push(...shown);
    } else if (k === "gated") {
      parts.push(v ? "gated" : "ungated");
    } else if (k === "windings") {
      if (v.length) parts.push(`turns ${v.join(" | ")}`);
    } else {
      parts.push(typeof v === "boolean" ? (v ? k : `not ${k}`)
        : `${k} ${typeof v === "object" ? JSON.stringify(v) : fmt(v)}`);
    }
  }
  return parts.join(", ");
}

/** The short label of a region's marker: its count (≥ a lower bound). */
function markerText(region) {
  const n = region.components;
  if (n === null || n === undefined) return "?";
  return `${region.components_exact === false ? "≥" : ""}${n}`;
}

function mapFrame(canvas, axes) {
  const pad = { l: 56, r: 16, t: 14, b: 44 };
  const [w, h] = [canvas.width - pad.l - pad.r, canvas.height - pad.t - pad.b];
  const [ax, ay] = axes;
  const to = (p) => [pad.l + w * (p[0] - ax.min) / (ax.max - ax.min),
                     pad.t + h * (1 - (p[1] - ay.min) / (ay.max - ay.min))];
  const from = (x, y) => [ax.min + (x - pad.l) / w * (ax.max - ax.min),
                          ay.min + (1 - (y - pad.t) / h) * (ay.max - ay.min)];
  return { to, from, sx: w / (ax.max - ax.min), sy: h / (ay.max - ay.min), pad, w, h };
}

function drawMap(error = "") {
  const canvas = $("map");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const req = mapView.request;
  canvas.dataset.provisional = String(Boolean(mapView.answer && mapView.provisional));
  if (!req) {
    ctx.fillStyle = "#222"; ctx.font = "13px sans-serif";
    const surfaces = state.space && state.space.surfaces && state.space.surfaces.length;
    ctx.fillText(!state.linkage ? "" : surfaces ? "no map: two degrees of freedom"
      : "choose two different bars", 20, 30);
    return;
  }
  const f = mapFrame(canvas, req.axes);
  mapView.frame = f;
  ctx.strokeStyle = "#888"; ctx.lineWidth = 1; ctx.strokeRect(f.pad.l, f.pad.t, f.w, f.h);
  ctx.fillStyle = "#222"; ctx.font = "12px sans-serif";
  for (let k = 0; k <= 4; k++) {
    const vx = req.axes[0].min + k * (req.axes[0].max - req.axes[0].min) / 4;
    const vy = req.axes[1].min + k * (req.axes[1].max - req.axes[1].min) / 4;
    const [x] = f.to([vx, req.axes[1].min]);
    const [, y] = f.to([req.axes[0].min, vy]);
    ctx.textAlign = "center"; ctx.fillText(fmt(vx, 3), x, f.pad.t + f.h + 16);
    ctx.textAlign = "right"; ctx.fillText(fmt(vy, 3), f.pad.l - 6, y + 4);
  }
  ctx.textAlign = "center";
  ctx.fillText(`length of ${req.axes[0].bar}`, f.pad.l + f.w / 2, f.pad.t + f.h + 34);
  ctx.save(); ctx.translate(14, f.pad.t + f.h / 2); ctx.rotate(-Math.PI / 2);
  ctx.fillText(`length of ${req.axes[1].bar}`, 0, 0); ctx.restore();
  ctx.textAlign = "left";
  const answer = mapView.answer;
  if (!answer) {
    const failed = error || mapView.error;
    ctx.fillStyle = failed ? "#a30000" : "#222";
    ctx.fillText(failed ? "no map: see the status line" : "computing…", f.pad.l + 12,
                 f.pad.t + 24);
    return;
  }
  ctx.save();
  ctx.beginPath(); ctx.rect(f.pad.l, f.pad.t, f.w, f.h); ctx.clip();
  ctx.strokeStyle = "#c51b7d"; ctx.lineWidth = 2;
  ctx.setLineDash(mapView.provisional ? [6, 4] : []);
  for (const curve of answer.curves) {
    ctx.beginPath();
    curve.forEach((p, i) => (i ? ctx.lineTo(...f.to(p)) : ctx.moveTo(...f.to(p))));
    ctx.stroke();
  }
  const here = req.axes.map((a) => barLength(req.linkage,
                                             req.linkage.bars.find((b) => b.id === a.bar)));
  const margin = mapView.margin;
  if (margin && typeof margin.margin === "number") {
    const [cx, cy] = f.to(here);
    ctx.fillStyle = "rgba(49, 130, 189, 0.18)"; ctx.strokeStyle = "#08519c"; ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.ellipse(cx, cy, margin.margin * f.sx, margin.margin * f.sy, 0, 0, TAU);
    ctx.fill(); ctx.stroke();
    if (margin.nearest && req.axes.every((a) => a.bar in margin.nearest)) {
      const [nx, ny] = f.to(req.axes.map((a) => margin.nearest[a.bar]));
      ctx.fillStyle = "#08519c"; ctx.beginPath(); ctx.arc(nx, ny, 4, 0, TAU); ctx.fill();
      ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(nx, ny); ctx.stroke();
    }
  }
  ctx.setLineDash([]);
  star(ctx, ...f.to(here));
  ctx.restore();
  answer.regions.forEach((region, k) => {
    const [x, y] = f.to(region.point);
    ctx.fillStyle = GATED_FILL[region.gated] || "#fff"; ctx.strokeStyle = "#222";
    ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(x, y, 9, 0, TAU); ctx.fill(); ctx.stroke();
    ctx.fillStyle = "#111"; ctx.font = "bold 11px sans-serif"; ctx.textAlign = "center";
    ctx.fillText(markerText(region), x, y + 4);
    ctx.font = "10px sans-serif";
    ctx.fillText(`R${k}`, x, y - 13);
    if (region.tau_signs && region.tau_signs.length) {
      // beneath the marker, or above its name where the frame's edge is near
      const below = y + 24 < f.pad.t + f.h;
      ctx.fillText(signsText(region.tau_signs[0].signs), x, below ? y + 21 : y - 25);
    }
    ctx.textAlign = "left";
  });
  mapLegend(ctx, f, answer);
  if (mapView.provisional) { // a stamp in the frame's lower right corner
    ctx.font = "bold 12px sans-serif"; ctx.textAlign = "right"; ctx.fillStyle = "#8a3b00";
    ctx.fillText("provisional: the full map follows", f.pad.l + f.w - 6, f.pad.t + f.h - 8);
    ctx.textAlign = "left";
  }
  // where each region's marker is in CSS pixels (for tests and assistive tools)
  const k = canvas.getBoundingClientRect().width / canvas.width;
  canvas.dataset.markers = JSON.stringify(answer.regions.map((r) => f.to(r.point).map((v) =>
    Math.round(v * k * 10) / 10)));
  canvas.dataset.regions = String(answer.regions.length);
  canvas.dataset.curves = String(answer.curves.length);
  canvas.dataset.draws = String(Number(canvas.dataset.draws || 0) + 1);
}

/** The map's legend, top left inside the frame: what the markers' fill and signs mean. */
function mapLegend(ctx, f, answer) {
  const rows = [];
  if (answer.regions.some((r) => r.gated === true || r.gated === false)) {
    rows.push([GATED_FILL.true, "gated: no rotor completes a turn"],
              [GATED_FILL.false, "ungated: the rotors turn fully"]);
  }
  const cell = answer.regions.find((r) => r.tau_signs && r.tau_signs.length);
  if (cell) rows.push([null, `(τ1,τ2,τ3) of the ${cell.tau_signs[0].cell} four-bar`]);
  if (answer.regions.some((r) => r.components_exact === false)) {
    rows.push([null, "≥n: a lower bound (n traced)"]);
  }
  if (!rows.length) return;
  ctx.font = "11px sans-serif";
  const width = Math.max(...rows.map(([, t]) => ctx.measureText(t).width)) + 30;
  const [x0, y0] = [f.pad.l + 6, f.pad.t + 6];
  ctx.fillStyle = "rgba(255, 255, 255, 0.88)"; ctx.strokeStyle = "#888"; ctx.lineWidth = 1;
  ctx.fillRect(x0, y0, width, 16 * rows.length + 6);
  ctx.strokeRect(x0, y0, width, 16 * rows.length + 6);
  rows.forEach(([fill, t], i) => {
    const y = y0 + 14 + 16 * i;
    if (fill) {
      ctx.fillStyle = fill; ctx.strokeStyle = "#222";
      ctx.beginPath(); ctx.arc(x0 + 11, y - 4, 5, 0, TAU); ctx.fill(); ctx.stroke();
    }
    ctx.fillStyle = "#111"; ctx.textAlign = "left";
    ctx.fillText(t, x0 + 22, y);
  });
  $("map").dataset.legend = JSON.stringify(rows.map(([, t]) => t));
}

function star(ctx, x, y) {
  ctx.beginPath();
  for (let k = 0; k < 10; k++) {
    const r = k % 2 ? 4 : 10;
    const a = -Math.PI / 2 + k * Math.PI / 5;
    ctx.lineTo(x + r * Math.cos(a), y + r * Math.sin(a));
  }
  ctx.closePath();
  ctx.fillStyle = "#ffd92f"; ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5;
  ctx.fill(); ctx.stroke();
}

/** What each field of a region means, from the service's own OpenAPI document (RegionOut). */
let regionFieldDocs = null;
async function loadRegionFieldDocs() {
  if (regionFieldDocs) return regionFieldDocs;
  try {
    const spec = await request("openapi.json", undefined, "json");
    const props = spec.components.schemas.RegionOut.properties;
    regionFieldDocs = Object.fromEntries(Object.entries(props).map(([k, v]) => [k,
      String(v.description || v.title || "").replace(/``/g, "")]));
  } catch (err) {
    regionFieldDocs = {}; // the legend then says "as the service gives it"
  }
  return regionFieldDocs;
}

/** The legend of the labels' extra fields (tau signs, gated, windings, ...): each field that a
 * region of the answer has, with the service's description of it and how the label shows it. */
async function showRegionFields(answer) {
  const box = $("region-fields");
  const fields = [...new Set(answer ? answer.regions.flatMap((r) => Object.keys(r)
    .filter((k) => !REGION_BASE.has(k) && r[k] !== null && r[k] !== undefined)) : [])];
  if (!fields.length) { box.replaceChildren(); return; }
  const docs = await loadRegionFieldDocs();
  if (mapView.answer !== answer) return;
  box.replaceChildren(...fields.flatMap((k) => {
    const dt = document.createElement("dt");
    dt.textContent = k;
    dt.dataset.field = k;
    const dd = document.createElement("dd");
    const bool = answer.regions.some((r) => typeof r[k] === "boolean");
    const how = k === "gated" ? 'shown as "gated" or "ungated"'
      : k === "tau_signs" ? 'shown as "τ <cell> <signs>"'
      : k === "windings" ? 'shown as "turns <pattern>"'
      : bool ? `shown as "${k}" or "not ${k}"` : `shown as "${k} <value>"`;
    dd.textContent = `${docs[k] || "as the service gives it"} (${how})`;
    return [dt, dd];
  }));
}

function showRegions() {
  const answer = mapView.answer;
  const list = $("regions");
  showRegionFields(answer);
  if (!answer) { list.replaceChildren(); return; }
  list.replaceChildren(...answer.regions.map((region, k) => {
    const b = document.createElement("button");
    b.type = "button";
    b.className = "region";
    b.dataset.region = String(k);
    b.dataset.components = String(region.components ?? "");
    b.dataset.gated = String(region.gated ?? "");
    b.dataset.tau = region.tau_signs && region.tau_signs.length
      ? signsText(region.tau_signs[0].signs) : "";
    b.textContent = `R${k}: ${regionLabel(region)} at (${fmt(region.point[0])}, ` +
      `${fmt(region.point[1])})`;
    b.title = region.signature || "";
    b.addEventListener("click", () => loadRegion(k));
    return b;
  }));
}

/** Load the linkage at a region's sample lengths (the service projects the configuration). */
function loadRegion(k) {
  const answer = mapView.answer;
  const req = mapView.request;
  if (!answer || !req) return;
  const region = answer.regions[k];
  if (region.components === 0) {
    state.tasks.set("map region", { state: "error", message: `R${k} is empty: no configuration ` +
      "has these lengths" });
    showTasks();
    return;
  }
  const lengths = Object.fromEntries(req.axes.map((a, i) => [a.bar, region.point[i]]));
  const linkage = withLengths(req.linkage, lengths);
  forgetParams(`the sample of map region R${k}`);
  markChange();
  $("linkage-json").value = JSON.stringify(linkage, null, 1);
  useLinkage(linkage, `map region R${k}`);
}

function mapClick(event) {
  const f = mapView.frame;
  const answer = mapView.answer;
  if (!f || !answer) return;
  const canvas = $("map");
  const [x, y] = canvasPoint(canvas, event);
  let best = null;
  answer.regions.forEach((region, k) => {
    const [rx, ry] = f.to(region.point);
    const d = Math.hypot(rx - x, ry - y);
    if (d < 16 && (!best || d < best.d)) best = { d, k };
  });
  if (best) loadRegion(best.k);
}

/** Ask for the map and (unless `margin` is false) the margin of the linkage shown. While a drag
 * goes on (`quick`) the searches get QUICK_S seconds, so that the map follows the hand; an answer
 * cut short is then asked again with the service's own budget (`refine`), the quick one drawn
 * meanwhile. */
function loadMap(generation, { quick = false, refine = false, margin = true } = {}) {
  const req = refine ? mapView.request : mapRequest();
  mapView.error = "";
  if (!refine) {
    mapView.request = req;
    mapView.answer = null;
    mapView.provisional = false;
    mapView.margin = null;
    $("margin").textContent = "";
    showRegions();
    drawMap();
  }
  if (!req) { $("map-caption").textContent = ""; return; }
  const [x, y] = req.axes.map((a) => a.bar);
  // a quick map is provisional: it is always asked again in full (see quickDone)
  const options = quick ? { options: QUICK_MAP } : {};
  const again = () => quick;
  if (!refine) $("map-caption").textContent = `${x} × ${y}: computing…`;
  if (quick) mapView.quick = { req, pending: 2, cut: false }; // the map's and the margin's
  call("v1/analysis/critical-values", { ...req, ...options }, { task: "map", generation })
    .then((answer) => {
      if (generation !== state.generation || mapView.request !== req) return;
      mapView.answer = answer;
      mapView.provisional = quick;
      const cut = quick ? ` (provisional: resolution ${QUICK_MAP.resolution}, curves from ` +
        `${QUICK_MAP.seeds_per_axis}×${QUICK_MAP.seeds_per_axis} seed lengths; the full map ` +
        "follows)" : answer.search && answer.search.complete === false
        ? ` (search cut short: ${answer.search.reason}; regions may be missing)` : "";
      $("map-caption").textContent = `${x} × ${y}: ${answer.regions.length} regions, ` +
        `${answer.curves.length} curves${cut}; the star is the linkage`;
      showRegions();
      drawMap();
      // from the change to the first map drawn (and, apart, to the refined one)
      const ms = String(Math.round(performance.now() - state.changed));
      $("map").dataset[refine ? "refinedMs" : "latencyMs"] = ms;
      // the first drawing with a curve and a counted region: what the hand sees first
      if (!$("map").dataset.usefulMs && answer.curves.length &&
          answer.regions.some((r) => r.components !== null && r.components !== undefined)) {
        $("map").dataset.usefulMs = ms;
      }
      if (quick) quickDone(generation, req, again());
    }).catch((err) => {
      if (err.superseded || generation !== state.generation) return;
      if (quick) quickDone(generation, req, false);
      $("map-caption").textContent = `${x} × ${y}: no map`;
      mapView.error = err.message;
      drawMap();
    });
  if (margin) loadMargin(generation, req, { quick, refine });
}

/** One of the map's and the margin's quick answers is in (or failed): once both are, and either
 * was cut short, both are asked again in full REFINE_AFTER_MS later (a refinement started sooner
 * would abort the margin's quick request). */
function quickDone(generation, req, cut) {
  const q = mapView.quick;
  if (!q || q.req !== req) return;
  q.cut = q.cut || cut;
  q.pending -= 1;
  if (q.pending > 0 || !q.cut) return;
  setTimeout(() => {
    if (generation === state.generation && mapView.request === req) {
      loadMap(generation, { refine: true });
    }
  }, REFINE_AFTER_MS);
}

/** Ask for the robustness margin in the map's two lengths (QUICK_S seconds if `quick`). */
function loadMargin(generation, req, { quick = false, refine = false } = {}) {
  const [x, y] = req.axes.map((a) => a.bar);
  const options = quick ? { options: { time_budget_s: QUICK_S } } : {};
  const body = { linkage: req.linkage, adjustable: [x, y], ...options };
  call("v1/analysis/robustness", body, { task: "margin", generation }).then((answer) => {
    if (generation !== state.generation || mapView.request !== req) return;
    mapView.margin = answer;
    $("margin").textContent = typeof answer.margin === "number"
      ? `robustness margin in ${x}, ${y}: ${fmt(answer.margin, 6)} (${answer.method}, ` +
        `${answer.guarantee}); the disc has this radius`
      : `no critical value found within the search (${answer.message})`;
    $("map").dataset.margin = typeof answer.margin === "number" ? fmt(answer.margin, 6) : "";
    const ms = String(Math.round(performance.now() - state.changed));
    $("map").dataset[refine ? "marginRefinedMs" : "marginLatencyMs"] = ms;
    drawMap();
    if (quick) quickDone(generation, req, answer.search && answer.search.complete === false);
  }).catch((err) => {
    if (err.superseded || generation !== state.generation) return;
    if (quick) quickDone(generation, req, false);
    $("margin").textContent = "no margin (see the status line)";
  });
}

function startMap() {
  $("map").addEventListener("click", mapClick);
  for (const id of ["axis-x", "axis-y", "axis-range"]) {
    $(id).addEventListener("change", () => { if (state.linkage) loadMap(state.generation); });
  }
  state.listeners.push((generation, what) => {
    // The map waits for the configuration space, which the other panels need first (on two
    // workers two full searches side by side would each take twice as long), except during a
    // drag: then the map's search is short (QUICK_S) and runs beside the space's quick search,
    // the margin's after it, so that both follow the hand.
    if (what === "linkage") {
      mapAxesChoice(state.linkage);
      mapView.request = null;
      mapView.answer = null;
      mapView.margin = null;
      $("map-caption").textContent = "waiting for the configuration space";
      $("margin").textContent = "";
      showRegions();
      drawMap();
      // (after the space's request is sent: the workers take requests in order)
      if (state.quick) {
        setTimeout(() => generation === state.generation &&
          loadMap(generation, { quick: true, margin: false }), 0);
      }
    } else if (what === "space" && state.space.surfaces && state.space.surfaces.length) {
      // two degrees of freedom: the service's maps and margins trace curves (one degree); a
      // quick map asked during a drag was refused with a 422, which is no error of this space
      for (const task of ["map", "margin"]) {
        const c = state.controllers.get(task);
        if (c) c.abort();
        state.tasks.delete(task);
      }
      showTasks();
      mapView.request = null; mapView.answer = null; mapView.margin = null;
      $("map-caption").textContent = "no map: maps of critical values need one degree of " +
        "freedom";
      $("margin").textContent = "";
      showRegions();
      drawMap();
    } else if ((what === "space" || what === "space-failed") && state.drawable) {
      if (!state.quick) loadMap(generation);
      else if (mapView.request) loadMargin(generation, mapView.request, { quick: true });
    } else if (what === "cleared") {
      mapView.request = null; mapView.answer = null; mapView.margin = null;
      $("map-caption").textContent = "no map";
      $("margin").textContent = "";
      showRegions();
      drawMap();
    }
  });
}
