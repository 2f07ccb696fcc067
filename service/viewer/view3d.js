// The 3D view: the components in three chosen coordinates (rotor angles, as in the paper's
// Figs. 2c and 5d, or vertex coordinates), drawn on a canvas by a rotation matrix and an
// orthographic projection; drag or the arrow keys rotate, a click picks the nearest point. A
// space with two degrees of freedom is drawn as its triangulated surfaces (surface3d.js).
// No library: the projection is a dozen lines, and the house rule is never to vendor code.
"use strict";

const view3 = { yaw: 0.6, pitch: 0.35, drag: null, projected: [] };

function coordinateChoices(linkage) {
  const dim = linkage.dimension || 2;
  const out = rotorsOf(linkage).map((r) => [`angle:${r.bar}`, `angle of ${r.bar}`]);
  for (const v of linkage.vertices) {
    if (pinned(v, dim)) continue;
    ["x", "y", "z"].slice(0, dim).forEach((a, i) => out.push([`${a}:${v.id}:${i}`,
                                                             `${a} of ${v.id}`]));
  }
  return out;
}

function choose3d(linkage, surfaces = false) {
  const choices = coordinateChoices(linkage);
  const defaults = surfaces ? surfaceChoice(linkage, choices) : choices.map(([v]) => v);
  const kept = ["d3-x", "d3-y", "d3-z"].map((id) => $(id).value);
  // the choices made stay while the kind of answer (curves or surfaces) stays
  const keep = Boolean(view3.surfaceAxes) === surfaces;
  ["d3-x", "d3-y", "d3-z"].forEach((id, k) => {
    const sel = $(id);
    sel.replaceChildren(...choices.map(([v, label]) => new Option(label, v)));
    if (keep && choices.some(([v]) => v === kept[k])) sel.value = kept[k];
    else if (defaults.length) sel.value = defaults[Math.min(k, defaults.length - 1)];
  });
  view3.surfaceAxes = surfaces;
}

/** One coordinate along a component: [values], and whether it is an angle (wrapped). */
function coordinate(comp, key) {
  const [kind, id, axis] = key.split(":");
  if (kind === "angle") return { values: comp.angles[id].map(wrap), angle: true };
  return { values: comp.positions[id].map((p) => p[Number(axis)]), angle: false };
}

function rotation() {
  const [cy, sy, cp, sp] = [Math.cos(view3.yaw), Math.sin(view3.yaw), Math.cos(view3.pitch),
                            Math.sin(view3.pitch)];
  // yaw about the vertical axis, then pitch about the horizontal one
  return [[cy, 0, sy], [sp * sy, cp, -sp * cy], [-cp * sy, sp, cp * cy]];
}

function draw3d() {
  const canvas = $("view3d");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  view3.projected = [];
  const answer = state.space;
  const keys = ["d3-x", "d3-y", "d3-z"].map((id) => $(id).value);
  ctx.fillStyle = "#222"; ctx.font = "13px sans-serif";
  canvas.dataset.surfaces = "0";
  if (!answer || keys.some((k) => !k)) {
    ctx.fillStyle = view3.failed ? "#a30000" : "#222";
    ctx.fillText(view3.failed ? "no configuration space: see the status line"
      : state.linkage ? "waiting for the configuration space" : "", 20, 30);
    return;
  }
  const surfaces = answer.surfaces || [];
  const comps = answer.components.map((c) => keys.map((k) => coordinate(c, k)));
  const meshes = surfaces.map((surf) => keys.map((k) => surfaceCoordinate(surf, k)));
  // each axis scaled to [-1, 1]: angles over [-π, π], coordinates over their range
  const ranges = keys.map((key, a) => {
    if (key.startsWith("angle:")) return [-Math.PI, Math.PI];
    const all = comps.concat(meshes).flatMap((c) => c[a].values);
    const [lo, hi] = [Math.min(...all), Math.max(...all)];
    return hi - lo > 1e-12 ? [lo, hi] : [lo - 1, hi + 1];
  });
  const norm = (a, v) => 2 * (v - ranges[a][0]) / (ranges[a][1] - ranges[a][0]) - 1;
  const R = rotation();
  const s = 0.32 * Math.min(canvas.width, canvas.height);
  const project = (p) => {
    const q = R.map((row) => row[0] * p[0] + row[1] * p[1] + row[2] * p[2]);
    return [canvas.width / 2 + s * q[0], canvas.height / 2 - s * q[1], q[2]];
  };
  // the cube and its axes
  ctx.strokeStyle = "#bbb"; ctx.lineWidth = 1;
  for (const a of [0, 1, 2]) {
    for (const u of [-1, 1]) {
      for (const v of [-1, 1]) {
        const p = [0, 0, 0]; const q = [0, 0, 0];
        p[a] = -1; q[a] = 1;
        p[(a + 1) % 3] = q[(a + 1) % 3] = u;
        p[(a + 2) % 3] = q[(a + 2) % 3] = v;
        ctx.beginPath(); ctx.moveTo(...project(p).slice(0, 2));
        ctx.lineTo(...project(q).slice(0, 2)); ctx.stroke();
      }
    }
  }
  keys.forEach((k, a) => {
    const tip = [-1, -1, -1];
    tip[a] = 1.25;
    const [x, y] = project(tip);
    ctx.fillStyle = "#222";
    ctx.fillText($(["d3-x", "d3-y", "d3-z"][a]).selectedOptions[0].textContent, x - 20, y);
  });
  if (surfaces.length) {
    view3.projected = drawSurfaces(ctx, answer, keys, project, norm);
  }
  comps.forEach((c, k) => {
    ctx.strokeStyle = COLOURS[k % COLOURS.length]; ctx.lineWidth = 2;
    ctx.beginPath();
    const n = c[0].values.length;
    for (let i = 0; i < n; i++) {
      const p = [0, 1, 2].map((a) => norm(a, c[a].values[i]));
      const [x, y] = project(p);
      view3.projected.push({ x, y, component: k, index: i });
      const jump = i > 0 && c.some((axis) => axis.angle &&
                                   Math.abs(axis.values[i] - axis.values[i - 1]) > Math.PI);
      if (i === 0 || jump) ctx.moveTo(x, y); else ctx.lineTo(x, y);
    }
    ctx.stroke();
  });
  // critical points by kind, as on the configuration space
  const rotor = rotorsByBar();
  for (const cp of answer.critical_points) {
    const p = keys.map((key, a) => {
      const [kind, id, axis] = key.split(":");
      return norm(a, kind === "angle" ? rotorAngle(cp.configuration, rotor[id])
        : cp.configuration[id][Number(axis)]);
    });
    if (p.every(Number.isFinite)) marker(ctx, cp.kind, ...project(p).slice(0, 2));
  }
  if (state.at) {
    const c = state.at.surface !== undefined ? meshes[state.at.surface]
      : comps[state.at.component];
    const [x, y] = project([0, 1, 2].map((a) => norm(a, c[a].values[state.at.index])));
    ctx.fillStyle = "#ffd92f"; ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(x, y, 6, 0, TAU); ctx.fill(); ctx.stroke();
  }
  canvas.dataset.yaw = view3.yaw.toFixed(3);
  canvas.dataset.pitch = view3.pitch.toFixed(3);
  canvas.dataset.draws = String(Number(canvas.dataset.draws || 0) + 1);
}

function pick3d(event) {
  const canvas = $("view3d");
  const [x, y] = canvasPoint(canvas, event);
  let best = null;
  for (const p of view3.projected) {
    const d = Math.hypot(p.x - x, p.y - y);
    if (!best || d < best.d) best = { d, ...p };
  }
  if (state.space && state.space.surfaces && state.space.surfaces.length) {
    best = pickSurfaceVertex(view3.projected, x, y);
    if (!best) return;
    stopAnimation();
    state.at = { surface: best.surface, index: best.index };
    canvas.dataset.picked = JSON.stringify(state.at);
    showAt();
    return;
  }
  if (!best || best.d > 20) return;
  stopAnimation();
  state.at = { component: best.component, index: best.index };
  canvas.dataset.picked = JSON.stringify(state.at);
  showAt();
}

function start3d() {
  const canvas = $("view3d");
  canvas.addEventListener("pointerdown", (e) => {
    view3.drag = { x: e.clientX, y: e.clientY, yaw: view3.yaw, pitch: view3.pitch, moved: 0 };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointermove", (e) => {
    const d = view3.drag;
    if (!d) return;
    d.moved = Math.max(d.moved, Math.hypot(e.clientX - d.x, e.clientY - d.y));
    view3.yaw = d.yaw + 0.01 * (e.clientX - d.x);
    view3.pitch = Math.max(-1.5, Math.min(1.5, d.pitch + 0.01 * (e.clientY - d.y)));
    draw3d();
  });
  canvas.addEventListener("pointerup", (e) => {
    const d = view3.drag;
    view3.drag = null;
    if (d && d.moved < 4) pick3d(e); // a click, not a rotation
  });
  canvas.addEventListener("keydown", (e) => {
    const turn = { ArrowLeft: [-0.1, 0], ArrowRight: [0.1, 0], ArrowUp: [0, -0.1],
                   ArrowDown: [0, 0.1] }[e.key];
    if (!turn) return;
    view3.yaw += turn[0];
    view3.pitch = Math.max(-1.5, Math.min(1.5, view3.pitch + turn[1]));
    draw3d();
    e.preventDefault();
  });
  for (const id of ["d3-x", "d3-y", "d3-z"]) $(id).addEventListener("change", draw3d);
  state.listeners.push((generation, what) => {
    if (what !== "at") view3.failed = what === "space-failed" || what === "cleared";
    if (what === "linkage") choose3d(state.linkage, view3.surfaceAxes);
    const surfaces = Boolean(state.space && state.space.surfaces && state.space.surfaces.length);
    if ((what === "space" || what === "space-refined") && surfaces !== view3.surfaceAxes) {
      choose3d(state.linkage, surfaces);
    }
    if (what !== "at") showSurfaceList(state.space);
    draw3d();
  });
}
