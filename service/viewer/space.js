// The configuration-space panel: components in two rotor angles with tick labels on both axes,
// critical points by kind with their rays, the tangent form's arrows (from the service's
// /v1/analysis/rigidity at points along each component) and the segments between critical
// points, selectable. The plotting functions are shared with the splitting panel.
"use strict";

const TICKS = [[-Math.PI, "−π"], [-Math.PI / 2, "−π/2"], [0, "0"], [Math.PI / 2, "π/2"],
               [Math.PI, "π"]];
const ARROWS_PER_COMPONENT = 8;
const ARROWS_AT_MOST = 32; // requests per answer: a chain's 32 components get one arrow each
const space = { pieces: [], selected: null, arrows: [] };

const wrap = (a) => ((a + Math.PI) % TAU + TAU) % TAU - Math.PI;

function spaceAxesChoice(linkage) {
  const bars = rotorsOf(linkage).map((r) => r.bar);
  for (const [id, pick] of [["space-x", 0], ["space-y", 1]]) {
    const sel = $(id);
    const keep = sel.value;
    sel.replaceChildren(...bars.map((b) => new Option(b, b)));
    if (bars.includes(keep)) sel.value = keep;
    else if (bars.length) sel.value = bars[Math.min(pick, bars.length - 1)];
  }
  if (bars.length > 1 && $("space-x").value === $("space-y").value) {
    $("space-y").value = bars.find((b) => b !== $("space-x").value);
  }
}

function spaceAxes() {
  const axes = [$("space-x").value, $("space-y").value].filter((a) => a);
  return axes.length === 2 && axes[0] !== axes[1] ? axes : [];
}

function spaceMap(canvas) {
  const pad = 48;
  const s = Math.min(canvas.width - 2 * pad, canvas.height - 2 * pad) / TAU;
  const ox = pad + 10 + s * Math.PI;
  const oy = canvas.height - pad - s * Math.PI;
  return { s, to: (a, b) => [ox + s * a, oy - s * b], from: (x, y) => [(x - ox) / s, (oy - y) / s] };
}

/** A hinge's frame: two unit vectors e1, e2 normal to its axis (pin -> pin2), e1 x e2 along it. */
function hingeFrame(conf, rotor) {
  const [p, q] = [conf[rotor.pin], conf[rotor.pin2]];
  const n = q.map((x, i) => x - p[i]);
  const len = Math.hypot(...n);
  const a = n.map((x) => x / len);
  // the coordinate axis least along the hinge, made normal to it
  const k = [0, 1, 2].reduce((best, i) => (Math.abs(a[i]) < Math.abs(a[best]) ? i : best), 0);
  const e = [0, 0, 0];
  e[k] = 1;
  const d = e.map((x, i) => x - a[k] * a[i]);
  const dl = Math.hypot(...d);
  const e1 = d.map((x) => x / dl);
  const e2 = [a[1] * e1[2] - a[2] * e1[1], a[2] * e1[0] - a[0] * e1[2], a[0] * e1[1] - a[1] * e1[0]];
  return { p, e1, e2 };
}

const dot = (u, v) => u.reduce((s, x, i) => s + x * v[i], 0);

/** Rotor angle of a configuration ({vertex: [x, y]} or, for a hinge, [x, y, z]). */
function rotorAngle(conf, rotor) {
  if (rotor.hinge) {
    const { p, e1, e2 } = hingeFrame(conf, rotor);
    const r = conf[rotor.tip].map((x, i) => x - p[i]);
    return Math.atan2(dot(r, e2), dot(r, e1));
  }
  const p = conf[rotor.pin];
  const q = conf[rotor.tip];
  return Math.atan2(q[1] - p[1], q[0] - p[0]);
}

/** How fast a rotor's angle turns along a velocity ({vertex: [dx, dy]}) at a configuration. */
function rotorRate(conf, velocity, rotor) {
  if (rotor.hinge) { // the pins do not move
    const { p, e1, e2 } = hingeFrame(conf, rotor);
    const r = conf[rotor.tip].map((x, i) => x - p[i]);
    const [x, y, vx, vy] = [dot(r, e1), dot(r, e2), dot(velocity[rotor.tip], e1),
                            dot(velocity[rotor.tip], e2)];
    return (x * vy - y * vx) / (x * x + y * y);
  }
  const p = conf[rotor.pin];
  const q = conf[rotor.tip];
  const [rx, ry] = [q[0] - p[0], q[1] - p[1]];
  const [vx, vy] = velocity[rotor.tip].map((v, i) => v - (velocity[rotor.pin] || [0, 0])[i]);
  return (rx * vy - ry * vx) / (rx * rx + ry * ry);
}

function rotorsByBar() {
  return Object.fromEntries(state.rotors.map((r) => [r.bar, r]));
}

/** The square of the torus with its ticks on both axes. */
function plotFrame(ctx, map, axes) {
  const [x0, y0] = map.to(-Math.PI, Math.PI);
  const [x1, y1] = map.to(Math.PI, -Math.PI);
  ctx.strokeStyle = "#888"; ctx.lineWidth = 1; ctx.strokeRect(x0, y0, x1 - x0, y1 - y0);
  ctx.fillStyle = "#222"; ctx.font = "12px sans-serif";
  for (const [v, label] of TICKS) {
    const [x] = map.to(v, 0);
    const [, y] = map.to(0, v);
    ctx.beginPath(); ctx.moveTo(x, y1); ctx.lineTo(x, y1 + 5); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(x0, y); ctx.lineTo(x0 - 5, y); ctx.stroke();
    ctx.textAlign = "center"; ctx.fillText(label, x, y1 + 18);
    ctx.textAlign = "right"; ctx.fillText(label, x0 - 8, y + 4);
  }
  ctx.textAlign = "center";
  ctx.fillText(axes[0] ? `angle of ${axes[0]}` : "", (x0 + x1) / 2, y1 + 36);
  ctx.save(); ctx.translate(x0 - 44, (y0 + y1) / 2); ctx.rotate(-Math.PI / 2);
  ctx.fillText(axes[1] ? `angle of ${axes[1]}` : "", 0, 0); ctx.restore();
  ctx.textAlign = "left";
  return { x0, y0, x1, y1 };
}

/** Polylines of a component in two rotor angles (cut where an angle wraps). */
function plotPath(ctx, map, comp, axes, from = 0, to = Infinity) {
  const a = comp.angles[axes[0]];
  const b = comp.angles[axes[1]];
  ctx.beginPath();
  const end = Math.min(to, a.length - 1);
  for (let i = from; i <= end; i++) {
    const [u, v] = [wrap(a[i]), wrap(b[i])];
    const p = map.to(u, v);
    const jump = i > from && (Math.abs(u - wrap(a[i - 1])) > Math.PI ||
                              Math.abs(v - wrap(b[i - 1])) > Math.PI);
    if (i === from || jump) ctx.moveTo(...p); else ctx.lineTo(...p);
  }
  ctx.stroke();
}

function plotComponents(ctx, map, answer, axes, style = {}) {
  answer.components.forEach((comp, k) => {
    ctx.strokeStyle = style.colour || COLOURS[k % COLOURS.length];
    ctx.lineWidth = style.width || 2;
    ctx.setLineDash(style.dash || []);
    plotPath(ctx, map, comp, axes);
  });
  ctx.setLineDash([]);
}

function marker(ctx, kind, x, y) {
  ctx.strokeStyle = KINDS[kind] || "#777"; ctx.fillStyle = KINDS[kind] || "#777";
  ctx.lineWidth = 3;
  ctx.beginPath();
  if (kind === "rigid") {
    ctx.fillRect(x - 5, y - 5, 10, 10);
  } else if (kind === "degenerate") {
    ctx.moveTo(x, y - 7); ctx.lineTo(x + 7, y); ctx.lineTo(x, y + 7); ctx.lineTo(x - 7, y);
    ctx.closePath(); ctx.fill();
  } else {
    ctx.moveTo(x - 6, y - 6); ctx.lineTo(x + 6, y + 6);
    ctx.moveTo(x + 6, y - 6); ctx.lineTo(x - 6, y + 6); ctx.stroke();
  }
}

function arrow(ctx, x, y, dx, dy, length, colour) {
  const n = Math.hypot(dx, dy);
  if (!(n > 0)) return false;
  const [ux, uy] = [dx / n, dy / n];
  const [tx, ty] = [x + ux * length, y + uy * length];
  ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = 1.5;
  ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(tx, ty); ctx.stroke();
  ctx.beginPath(); ctx.moveTo(tx, ty);
  ctx.lineTo(tx - 6 * ux + 3.5 * uy, ty - 6 * uy - 3.5 * ux);
  ctx.lineTo(tx - 6 * ux - 3.5 * uy, ty - 6 * uy + 3.5 * ux);
  ctx.closePath(); ctx.fill();
  return true;
}

/** Critical points by kind, with their rays +t0, -t0, +t1, -t1 (numbered 0..3) as arrows. */
function plotCritical(ctx, map, answer, axes) {
  const rotor = rotorsByBar();
  let rays = 0;
  for (const cp of answer.critical_points) {
    const ang = axes.map((bar) => rotorAngle(cp.configuration, rotor[bar]));
    const [x, y] = map.to(...ang);
    (cp.tangents || []).forEach((t, j) => {
      for (const sign of [1, -1]) {
        const d = axes.map((bar) => sign * rotorRate(cp.configuration, t, rotor[bar]));
        if (arrow(ctx, x, y, d[0], -d[1], 22, "#555")) {
          rays += 1;
          const n = Math.hypot(d[0], d[1]);
          ctx.fillStyle = "#333"; ctx.font = "10px sans-serif";
          ctx.fillText(String(2 * j + (sign > 0 ? 0 : 1)), x + 30 * d[0] / n - 3,
                       y - 30 * d[1] / n + 3);
        }
      }
    });
    marker(ctx, cp.kind, x, y);
    ctx.fillStyle = "#222"; ctx.font = "11px sans-serif";
    ctx.fillText(`#${cp.index}`, x + 8, y + 16);
  }
  return rays;
}

function drawSpace(error = "") {
  const canvas = $("space");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const axes = spaceAxes();
  const map = spaceMap(canvas);
  const box = plotFrame(ctx, map, axes);
  canvas.dataset.ticksX = canvas.dataset.ticksY = String(TICKS.length);
  const answer = state.space;
  const mid = [(box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2];
  ctx.textAlign = "center";
  if (!answer) {
    const text = error ? "no answer: see the status line" : (state.linkage ? "computing…" : "");
    ctx.fillStyle = error ? "#a30000" : "#222";
    ctx.fillText(text, ...mid);
    ctx.textAlign = "left";
    canvas.dataset.components = "";
    canvas.dataset.criticalPoints = "";
    showSegments();
    return;
  }
  if (axes.length < 2) {
    ctx.fillText("needs two rotors (bars with one pinned end)", ...mid);
  }
  ctx.textAlign = "left";
  if (axes.length === 2) {
    plotComponents(ctx, map, answer, axes);
    const sel = space.selected !== null && space.pieces[space.selected];
    if (sel) {
      ctx.strokeStyle = "#000"; ctx.lineWidth = 6; ctx.globalAlpha = 0.45;
      plotPath(ctx, map, answer.components[sel.component], axes, sel.from, sel.to);
      ctx.globalAlpha = 1;
    }
    canvas.dataset.tangentArrows = String(plotArrows(ctx, map, axes));
    canvas.dataset.rays = String(plotCritical(ctx, map, answer, axes));
    if (answer.surfaces && answer.surfaces.length) plotSurfacePoints(ctx, map, answer, axes);
    if (state.at && state.at.surface === undefined) {
      const comp = answer.components[state.at.component];
      const [x, y] = map.to(wrap(comp.angles[axes[0]][state.at.index]),
                            wrap(comp.angles[axes[1]][state.at.index]));
      ctx.fillStyle = "#ffd92f"; ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.arc(x, y, 6, 0, TAU); ctx.fill(); ctx.stroke();
    }
  }
  canvas.dataset.components = String(answer.components.length);
  canvas.dataset.criticalPoints = String(answer.critical_points.length);
  canvas.dataset.kinds = answer.critical_points.map((c) => c.kind).join(",");
  canvas.dataset.points = String(answer.components.reduce(
    (n, c) => n + (Object.values(c.angles)[0] || []).length, 0));
  canvas.dataset.lengths = state.linkage.bars.map((b) => barLength(state.linkage, b).toFixed(4))
    .join(",");
  canvas.dataset.draws = String(Number(canvas.dataset.draws) + 1);
}

/** A two-degree-of-freedom answer in two rotor angles: every mesh vertex of its surfaces as a
 * dot (the surfaces themselves are drawn in the 3D view), the configuration shown ringed. */
function plotSurfacePoints(ctx, map, answer, axes) {
  answer.surfaces.forEach((surf, s) => {
    const [a, b] = axes.map((bar) => surfaceCoordinate(surf, `angle:${bar}`).values);
    ctx.fillStyle = COLOURS[s % COLOURS.length];
    for (let i = 0; i < a.length; i++) {
      const [x, y] = map.to(a[i], b[i]);
      ctx.fillRect(x - 1, y - 1, 2, 2);
    }
    if (state.at && state.at.surface === s) {
      const [x, y] = map.to(a[state.at.index], b[state.at.index]);
      ctx.fillStyle = "#ffd92f"; ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.arc(x, y, 6, 0, TAU); ctx.fill(); ctx.stroke();
    }
  });
}

// -- the tangent form along the components ----------------------------------------------------

/** Arrows of the tangent form t(u) (paper, Eq. 5; Fig. 1b) at points along each component, as
 * the service's rigidity analysis gives it there (`tangent_form`: unit vector and orientation). */
function plotArrows(ctx, map, axes) {
  const rotor = rotorsByBar();
  const drawn = [];
  for (const a of space.arrows) {
    const d = axes.map((bar) => a.orientation * rotorRate(a.conf, a.vector, rotor[bar]));
    const [x, y] = map.to(...axes.map((bar) => rotorAngle(a.conf, rotor[bar])));
    if (arrow(ctx, x, y, d[0], -d[1], 16, "#b35806")) {
      drawn.push({ component: a.component, index: a.index, d });
    }
  }
  // each arrow's direction in the two angles (read back by the tests)
  $("space").dataset.arrows = JSON.stringify(drawn);
  return drawn.length;
}

async function loadArrows(generation) {
  const answer = state.space;
  const linkage = state.linkage;
  space.arrows = [];
  if (!answer || (linkage.dimension || 2) !== 2) return;
  const lengths = Object.fromEntries(linkage.bars.map((b) => [b.id, barLength(linkage, b)]));
  const samples = [];
  const per = Math.max(1, Math.min(ARROWS_PER_COMPONENT,
                                    Math.floor(ARROWS_AT_MOST / answer.components.length)));
  answer.components.slice(0, ARROWS_AT_MOST).forEach((comp, k) => {
    const n = Object.values(comp.positions)[0].length;
    for (let j = 0; j < per; j++) {
      const i = Math.floor((j + 0.5) * (n - 1) / per);
      samples.push({ component: k, index: i, conf: Object.fromEntries(
        Object.entries(comp.positions).map(([v, w]) => [v, w[i]])) });
    }
  });
  const found = await runTask("tangent form", generation, (signal) => Promise.all(
    samples.map(({ component, index, conf }) => request("v1/analysis/rigidity", {
      linkage: { ...linkage, vertices: linkage.vertices.map((v) => ({ ...v,
        position: conf[v.id] })), bars: linkage.bars.map((b) => ({ ...b,
        length: lengths[b.id] })) },
    }, "json", signal).then((r) => ({ component, index, conf, form: r.tangent_form })))));
  if (generation !== state.generation) return;
  space.arrows = found.filter((f) => f.form && f.form.orientation !== 0).map((f) => ({
    component: f.component, index: f.index, conf: f.conf, vector: f.form.vector,
    orientation: f.form.orientation }));
  drawSpace();
}

// -- answers of the space search: quick (during a drag), then refined -------------------------

/** Draw an answer of /v1/analysis/configuration-space for the linkage shown; `quick` is an
 * answer without the completeness proof (during a drag). */
function showSpace(answer, linkage, quick) {
  hingeAngles(answer);
  state.space = answer;
  state.spaceQuick = quick;
  state.at = nearestPoint(answer, linkage);
  const surfaces = Boolean(answer.surfaces && answer.surfaces.length);
  $("animate").disabled = !state.at || surfaces;
  $("space-caption").textContent = surfaces ? surfacesCaption(answer)
    : quick ? quickCaption(answer) : spaceCaption(answer);
  $("space").dataset.complete = String(!quick && (answer.search || {}).complete !== false);
  drawSpace();
  drawLinkage();
}

/** A 3D answer's components carry no angles: each hinge's angle about its axis is added here,
 * from the positions along each component (the answer's own numbers are left as they are). */
function hingeAngles(answer) {
  const hinges = state.rotors.filter((r) => r.hinge);
  for (const comp of answer.components) {
    const n = Object.values(comp.positions)[0].length;
    for (const r of hinges) {
      if (comp.angles[r.bar]) continue;
      comp.angles[r.bar] = Array.from({ length: n }, (_, i) => rotorAngle(Object.fromEntries(
        [r.pin, r.pin2, r.tip].map((v) => [v, comp.positions[v][i]])), r));
    }
  }
}

/** After a drag: the same linkage's full search (with the completeness proof) replaces the
 * quick answer; the listeners hear "space-refined" (the map has its own refinement). */
function refineSpace(generation) {
  const linkage = state.linkage;
  call("v1/analysis/configuration-space", { linkage }, { task: "configuration space", generation })
    .then((answer) => {
      if (generation !== state.generation || !state.drawable) return;
      showSpace(answer, linkage, false);
      $("space").dataset.refinedMs = String(Math.round(performance.now() - state.changed));
      for (const f of state.listeners) f(generation, "space-refined");
    })
    .catch(() => { /* the status line says it; the quick answer stays drawn */ });
}

/** The caption of an answer found without the completeness proof. */
function quickCaption(answer) {
  const plural = (k, word) => `${k} ${word}${k === 1 ? "" : "s"}`;
  const total = (answer.search || {}).components_total;
  const comps = Number.isInteger(total) && total > answer.components.length
    ? `${answer.components.length} of ${total} components traced`
    : plural(answer.components.length, "component");
  return `${comps}, ${plural(answer.critical_points.length, "critical point")} found ` +
    "(completeness not yet proved: the full search follows the drag)";
}

// -- segments between critical points --------------------------------------------------------

function flat(conf, ids) {
  return ids.flatMap((id) => conf[id]);
}

function nearestRay(cp, dir, ids) {
  let best = null;
  (cp.tangents || []).forEach((t, j) => {
    const v = flat(t, ids);
    const dot = v.reduce((s, x, i) => s + x * dir[i], 0);
    for (const [sign, ray] of [[1, 2 * j], [-1, 2 * j + 1]]) {
      if (!best || sign * dot > best.dot) best = { dot: sign * dot, ray };
    }
  });
  return best ? best.ray : null;
}

/** Where along each component's walk each segment of the answer lies: the walk is cut where it
 * passes through a critical point, and each piece is matched to the segment with the same ends
 * and rays. */
function segmentPieces(answer, linkage) {
  const ids = linkage.vertices.map((v) => v.id);
  const step = (answer.search && answer.search.step_max) || 0.1;
  const pieces = answer.segments.map(() => null);
  answer.components.forEach((comp, k) => {
    const n = Object.values(comp.positions)[0].length;
    const walk = Array.from({ length: n }, (_, i) => ids.flatMap((id) => comp.positions[id][i]));
    const hits = [];
    for (const c of comp.critical_points) {
      const cp = answer.critical_points.find((p) => p.index === c);
      if (!cp) continue;
      const target = flat(cp.configuration, ids);
      const d = walk.map((u) => Math.hypot(...u.map((x, i) => x - target[i])));
      for (let i = 0; i < n - (comp.closed ? 1 : 0); i++) {
        if (d[i] < step && (i === 0 || d[i] <= d[i - 1]) && (i === n - 1 || d[i] <= d[i + 1])) {
          hits.push({ i, cp });
        }
      }
    }
    hits.sort((p, q) => p.i - q.i);
    const count = comp.closed ? hits.length : hits.length - 1;
    for (let h = 0; h < count; h++) {
      const [a, b] = [hits[h], hits[(h + 1) % hits.length]];
      const to = b.i > a.i ? b.i : b.i + n - 1;
      if (to - a.i < 2) continue;
      const m = Math.max(1, Math.min(3, Math.floor((to - a.i) / 2)));
      const at = (i) => walk[i % (n - 1 || 1)];
      const dirA = at(a.i + m).map((x, i) => x - walk[a.i][i]);
      const dirB = at(to - m).map((x, i) => x - at(to)[i]);
      const [ra, rb] = [nearestRay(a.cp, dirA, ids), nearestRay(b.cp, dirB, ids)];
      const same = (s) => s.component === k && ((s.from === a.cp.index && s.to === b.cp.index &&
        s.from_ray === ra && s.to_ray === rb) || (s.from === b.cp.index && s.to === a.cp.index &&
        s.from_ray === rb && s.to_ray === ra));
      const j = answer.segments.findIndex((s, q) => pieces[q] === null && same(s));
      if (j >= 0) pieces[j] = { component: k, from: a.i, to, n };
    }
  });
  return pieces;
}

function showSegments() {
  const list = $("segments");
  const answer = state.space;
  if (!answer || !answer.segments.length) {
    list.replaceChildren();
    $("segments-caption").textContent = answer ? "no segments (no critical point joins branches)"
      : "";
    return;
  }
  $("segments-caption").textContent = `${answer.segments.length} segments between critical ` +
    "points (from the service; choose one to see it):";
  list.replaceChildren(...answer.segments.map((s, j) => {
    const b = document.createElement("button");
    b.type = "button";
    b.className = "segment";
    b.dataset.segment = String(j);
    b.setAttribute("aria-pressed", String(space.selected === j));
    b.textContent = `#${s.from} ray ${s.from_ray} → #${s.to} ray ${s.to_ray} ` +
      `(component ${s.component})`;
    b.disabled = !space.pieces[j];
    b.addEventListener("click", () => selectSegment(j));
    return b;
  }));
}

function selectSegment(j) {
  const piece = space.pieces[j];
  space.selected = j;
  $("space").dataset.selectedSegment = String(j);
  if (piece) {
    const mid = Math.floor((piece.from + piece.to) / 2) % (piece.n - 1 || 1);
    stopAnimation();
    state.at = { component: piece.component, index: mid };
  }
  showSegments();
  showAt();
}

// -- clicks and keys ----------------------------------------------------------------------------

function pick(event) {
  const answer = state.space;
  const axes = spaceAxes();
  if (!answer || axes.length < 2) return;
  const canvas = $("space");
  const [a, b] = spaceMap(canvas).from(...canvasPoint(canvas, event));
  let best = null;
  answer.components.forEach((comp, k) => {
    comp.angles[axes[0]].forEach((ang, i) => {
      const da = wrap(wrap(ang) - a);
      const db = wrap(wrap(comp.angles[axes[1]][i]) - b);
      const d = da * da + db * db;
      if (!best || d < best.d) best = { d, component: k, index: i };
    });
  });
  if (!best) return;
  stopAnimation();
  state.at = { component: best.component, index: best.index };
  const j = space.pieces.findIndex((p) => p && p.component === best.component &&
    ((best.index >= p.from && best.index <= p.to) ||
     (best.index + p.n - 1 >= p.from && best.index + p.n - 1 <= p.to)));
  if (j >= 0) { selectSegment(j); return; }
  showAt();
}

function spaceKeys(event) {
  const steps = { ArrowRight: 1, ArrowLeft: -1, PageUp: 10, PageDown: -10 };
  if (event.key in steps) { moveAlong(steps[event.key]); event.preventDefault(); }
}

function startSpace() {
  const canvas = $("space");
  canvas.addEventListener("click", pick);
  canvas.addEventListener("keydown", spaceKeys);
  for (const id of ["space-x", "space-y"]) $(id).addEventListener("change", () => drawSpace());
  state.listeners.push((generation, what) => {
    if (what === "linkage" || what === "cleared" || what === "space-failed") {
      space.pieces = []; space.selected = null; space.arrows = [];
      delete canvas.dataset.selectedSegment;
      canvas.dataset.tangentArrows = "0";
      showSegments();
    } else if (what === "space" || what === "space-refined") {
      space.pieces = segmentPieces(state.space, state.linkage);
      canvas.dataset.segments = String(space.pieces.filter((p) => p).length);
      showSegments();
      // a drag's quick answer gets no arrows (their requests would hold the workers the map
      // needs): the refined answer gets them
      if (what === "space-refined" || !state.quick) {
        loadArrows(generation).catch(() => { /* the status line says it */ });
      }
    }
  });
}
