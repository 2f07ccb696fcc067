// The linkage panel: the drawing, dragging a joint or a bar's length handle, the keyboard.
"use strict";

// -- the linkage, drawn and dragged -------------------------------------------------------------

function currentPositions() {
  const { space, at, linkage } = state;
  if (space && at && at.surface !== undefined) {
    return surfacePositions(space.surfaces[at.surface], at.index);
  }
  if (space && at) {
    const comp = space.components[at.component];
    return Object.fromEntries(Object.entries(comp.positions).map(([v, walk]) =>
      [v, walk[at.index]]));
  }
  return Object.fromEntries(linkage.vertices.map((v) => [v.id, v.position]));
}

function fit(canvas, points, pad = 30) {
  const xs = points.map((p) => p[0]);
  const ys = points.map((p) => p[1]);
  const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  const w = canvas.width - 2 * pad;
  const h = canvas.height - 2 * pad;
  const s = Math.min(w / Math.max(x1 - x0, 1e-9), h / Math.max(y1 - y0, 1e-9));
  const cx = (x0 + x1) / 2;
  const cy = (y0 + y1) / 2;
  const to = (p) => [canvas.width / 2 + s * (p[0] - cx), canvas.height / 2 - s * (p[1] - cy)];
  const from = (x, y) => [cx + (x - canvas.width / 2) / s, cy - (y - canvas.height / 2) / s];
  return { to, from, s };
}

function nearestPoint(space, linkage) {
  // Start where the linkage is: the point of the answer closest to the given positions.
  let best = null;
  (space.surfaces || []).forEach((surf, k) => {
    const n = Object.values(surf.positions)[0].length;
    for (let i = 0; i < n; i++) {
      let d = 0;
      for (const v of linkage.vertices) {
        d += surf.positions[v.id][i].reduce((acc, x, j) => acc + (x - v.position[j]) ** 2, 0);
      }
      if (!best || d < best.d) best = { d, surface: k, index: i };
    }
  });
  if (best) return { surface: best.surface, index: best.index };
  space.components.forEach((comp, k) => {
    const n = Object.values(comp.positions)[0].length;
    for (let i = 0; i < n; i++) {
      let d = 0;
      for (const v of linkage.vertices) {
        const p = comp.positions[v.id][i];
        d += p.reduce((acc, x, j) => acc + (x - v.position[j]) ** 2, 0);
      }
      if (!best || d < best.d) best = { d, component: k, index: i };
    }
  });
  return best && { component: best.component, index: best.index };
}

const view = { map: null, drag: null, focus: 0 }; // the drawing's frame and the drag under way

function drawLinkage() {
  const canvas = $("linkage");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const { linkage, space } = state;
  if (!linkage || !state.drawable) { canvas.dataset.handles = "{}"; return; }
  const dim = linkage.dimension || 2;
  const pos = currentPositions();
  if (!view.drag) { // a view that holds the whole motion, so that it does not jump
    let extent = Object.values(pos);
    if (space && state.at) {
      const comp = state.at.surface !== undefined ? space.surfaces[state.at.surface]
        : space.components[state.at.component];
      extent = extent.concat(...Object.values(comp.positions).map((w) =>
        w.filter((_, i) => i % 4 === 0)));
    }
    view.map = fit(canvas, extent.map((p) => p.slice(0, 2)));
  }
  const to = (p) => view.map.to(p);
  const handles = {};
  ctx.lineCap = "round";
  for (const bar of linkage.bars) {
    const [p, q] = bar.ends.map((v) => to(pos[v]));
    ctx.strokeStyle = "#555"; ctx.lineWidth = 4;
    ctx.beginPath(); ctx.moveTo(...p); ctx.lineTo(...q); ctx.stroke();
    const mid = [(p[0] + q[0]) / 2, (p[1] + q[1]) / 2];
    if (dim === 2) { // the length handle: drag it along the bar
      ctx.fillStyle = "#fff"; ctx.strokeStyle = "#345"; ctx.lineWidth = 1.5;
      ctx.fillRect(mid[0] - 4, mid[1] - 4, 8, 8); ctx.strokeRect(mid[0] - 4, mid[1] - 4, 8, 8);
      handles[`bar:${bar.id}`] = mid;
    }
    ctx.fillStyle = "#234"; ctx.font = "12px sans-serif";
    ctx.fillText(bar.id, mid[0] + 7, mid[1] - 7);
  }
  linkage.vertices.forEach((v, k) => {
    const [x, y] = to(pos[v.id]);
    handles[`vertex:${v.id}`] = [x, y];
    ctx.beginPath();
    if (pinned(v, dim)) {
      ctx.moveTo(x, y - 8); ctx.lineTo(x + 8, y + 6); ctx.lineTo(x - 8, y + 6); ctx.closePath();
      ctx.fillStyle = "#111"; ctx.fill();
    } else if (Array.isArray(v.fixed) && v.fixed.some(Boolean)) {
      ctx.rect(x - 6, y - 6, 12, 12); ctx.fillStyle = "#6a3d9a"; ctx.fill();
    } else {
      ctx.arc(x, y, 5, 0, TAU); ctx.fillStyle = "#fff"; ctx.fill();
      ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5; ctx.stroke();
    }
    if (document.activeElement === canvas && k === view.focus) {
      ctx.strokeStyle = "#0b57d0"; ctx.lineWidth = 2;
      ctx.beginPath(); ctx.arc(x, y, 11, 0, TAU); ctx.stroke();
    }
    ctx.fillStyle = "#111"; ctx.font = "11px sans-serif";
    ctx.fillText(v.id, x - 14, y + 18);
  });
  // where each handle is in CSS pixels (for tests and assistive tools)
  const r = canvas.getBoundingClientRect();
  const k = r.width / canvas.width;
  canvas.dataset.handles = JSON.stringify(Object.fromEntries(Object.entries(handles).map(
    ([h, [x, y]]) => [h, [Math.round(x * k * 10) / 10, Math.round(y * k * 10) / 10]])));
  const at = state.at;
  $("linkage-caption").textContent = `${state.source || "linkage"}: ` +
    (!at ? "as given" : at.surface !== undefined ? `surface ${at.surface}, mesh vertex ${at.index}`
      : `component ${at.component}, point ${at.index}`);
}

function canvasPoint(canvas, event) {
  const rect = canvas.getBoundingClientRect();
  return [(event.clientX - rect.left) * canvas.width / rect.width,
          (event.clientY - rect.top) * canvas.height / rect.height];
}

/** Edit the linkage as drawn: move a vertex (its bars take the new distances) or change one
 * bar's length, then ask again after a short pause (older requests are aborted). */
function edit(change) {
  const linkage = state.linkage;
  if (!linkage || !state.drawable) return;
  const pos = currentPositions();
  const vertices = linkage.vertices.map((v) => ({ ...v, position: pos[v.id].slice() }));
  let bars = linkage.bars.map((b) => ({ ...b }));
  const at = Object.fromEntries(vertices.map((v) => [v.id, v]));
  if (change.vertex) {
    at[change.vertex].position = change.position;
    bars = bars.map((b) => (b.ends.includes(change.vertex)
      ? { ...b, length: Math.hypot(...at[b.ends[0]].position.map(
        (x, i) => x - at[b.ends[1]].position[i])) } : b));
  } else if (change.bar) {
    bars = bars.map((b) => (b.id === change.bar ? { ...b, length: change.length } : b));
  }
  const edited = { ...linkage, vertices, bars };
  if (state.source && !state.source.endsWith("edited")) {
    forgetParams("edited on the drawing: choose a preset again to reset");
  }
  const source = state.source && !state.source.endsWith("edited")
    ? `${state.source}, edited` : (state.source || "edited");
  state.linkage = edited;
  state.source = source;
  state.at = null;
  state.space = null;
  markChange();
  drawLinkage();
  clearTimeout(view.timer);
  view.timer = setTimeout(() => {
    $("linkage-json").value = JSON.stringify(edited, null, 1);
    useLinkage(edited, source, true);
  }, DEBOUNCE_MS);
}

function grab(event) {
  const canvas = $("linkage");
  if (!state.linkage || !state.drawable || !view.map) return;
  const [x, y] = canvasPoint(canvas, event);
  const handles = JSON.parse(canvas.dataset.handles || "{}");
  const k = canvas.getBoundingClientRect().width / canvas.width;
  let best = null;
  for (const [h, [hx, hy]] of Object.entries(handles)) {
    const d = Math.hypot(hx / k - x, hy / k - y);
    if (d < 14 && (!best || d < best.d || (h.startsWith("vertex") && d < best.d + 4))) {
      best = { h, d };
    }
  }
  if (!best) return;
  const [kind, id] = [best.h.slice(0, best.h.indexOf(":")), best.h.slice(best.h.indexOf(":") + 1)];
  const pos = currentPositions();
  if (kind === "bar") {
    const bar = state.linkage.bars.find((b) => b.id === id);
    const [p, q] = bar.ends.map((v) => pos[v]);
    view.drag = { bar: id, start: view.map.from(x, y), length: barLength(state.linkage, bar),
                  dir: [q[0] - p[0], q[1] - p[1]].map((c) => c / Math.hypot(q[0] - p[0],
                                                                           q[1] - p[1])) };
  } else {
    view.drag = { vertex: id, depth: pos[id].slice(2) };
  }
  canvas.setPointerCapture(event.pointerId);
  event.preventDefault();
}

function dragMove(event) {
  if (!view.drag) return;
  const [x, y] = canvasPoint($("linkage"), event);
  const p = view.map.from(x, y);
  const d = view.drag;
  if (d.vertex) {
    edit({ vertex: d.vertex, position: [p[0], p[1], ...d.depth] });
  } else {
    // twice the move along the bar: both ends move apart as the handle is dragged
    const along = 2 * ((p[0] - d.start[0]) * d.dir[0] + (p[1] - d.start[1]) * d.dir[1]);
    edit({ bar: d.bar, length: Math.max(1e-3 * d.length, d.length + along) });
  }
}

function drop() {
  view.drag = null;
}

/** Keyboard: Tab to the drawing, [ and ] choose a vertex, the arrow keys move it. */
function linkageKeys(event) {
  if (!state.linkage || !state.drawable) return;
  const n = state.linkage.vertices.length;
  if (event.key === "[" || event.key === "]") {
    view.focus = (view.focus + (event.key === "]" ? 1 : n - 1)) % n;
    drawLinkage();
    event.preventDefault();
    return;
  }
  const step = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };
  if (!(event.key in step)) return;
  const v = state.linkage.vertices[view.focus];
  const p = currentPositions()[v.id];
  const h = 0.02 * Math.max(...state.linkage.bars.map((b) => barLength(state.linkage, b)));
  edit({ vertex: v.id, position: [p[0] + h * step[event.key][0], p[1] + h * step[event.key][1],
                                  ...p.slice(2)] });
  event.preventDefault();
}

// -- rigidity at the configuration shown ---------------------------------------------------------

/** First-order (and, at a critical configuration, second-order) readout of the configuration
 * shown, from /v1/analysis/rigidity and /v1/analysis/second-order; not while animating. */
function loadReadout(generation) {
  clearTimeout(view.readoutTimer);
  const el = $("readout");
  if (!state.linkage || !state.drawable || state.animation) { el.textContent = ""; return; }
  view.readoutTimer = setTimeout(async () => {
    const pos = currentPositions();
    const linkage = { ...state.linkage, bars: state.linkage.bars.map((b) => ({ ...b,
      length: barLength(state.linkage, b) })), vertices: state.linkage.vertices.map((v) =>
      ({ ...v, position: pos[v.id] })) };
    try {
      const r = await call("v1/analysis/rigidity", { linkage }, { task: "rigidity", generation });
      if (generation !== state.generation) return;
      let text = `here: rank ${r.rank} of J (E = ${r.n_constraints}, M = ${r.n_free}), ` +
        `${r.dof} zero mode${r.dof === 1 ? "" : "s"}, ${r.self_stresses.length} ` +
        `self-stress${r.self_stresses.length === 1 ? "" : "es"}, ` +
        (r.critical ? "critical" : "regular");
      if (r.tangent_form && r.tangent_form.orientation) {
        text += `, tangent form orientation ${r.tangent_form.orientation > 0 ? "+1" : "−1"}`;
      }
      if (r.critical) {
        const s = await call("v1/analysis/second-order", { linkage },
                             { task: "second order", generation });
        if (generation !== state.generation) return;
        text += `; second order: ${s.kind}` + (s.prestress_stable === null ? ""
          : `, prestress stable: ${s.prestress_stable}`);
      }
      el.textContent = text;
      el.dataset.rank = String(r.rank);
      el.dataset.dof = String(r.dof);
    } catch (err) {
      if (!err.superseded) el.textContent = "no readout (see the status line)";
    }
  }, 150);
}
