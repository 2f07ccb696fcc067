// The linkage viewer: calls the service's public JSON and figure endpoints only.
"use strict";

const API = new URL("..", window.location.href); // the service root (the viewer is /viewer/)
const TAU = 2 * Math.PI;
const COLOURS = ["#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf",
                 "#bcbd22", "#7f7f7f"];
const KINDS = { branch: "#d62728", rigid: "#111111", degenerate: "#ff7f0e" };
const $ = (id) => document.getElementById(id);

const state = {
  presets: [],
  linkage: null, // the linkage being looked at (as the API gives it)
  space: null, // the answer of /v1/analysis/configuration-space
  rotors: [], // [{bar, pin, tip}] bars with exactly one pinned end
  at: null, // {component, index}: the configuration shown
  generation: 0, // answers of older requests are dropped
  animation: null,
};

// -- talking to the service ---------------------------------------------------------------

let busy = 0;
function setBusy(delta) {
  busy += delta;
  document.body.dataset.busy = String(busy);
}

function status(text, error = false) {
  const el = $("status");
  el.textContent = text;
  el.classList.toggle("error", error);
}

async function call(path, body, accept = "json") {
  setBusy(1);
  try {
    const init = body === undefined ? {} : {
      method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body),
    };
    const res = await fetch(new URL(path, API), init);
    if (!res.ok) {
      let detail = `${res.status} ${res.statusText}`;
      try { const p = await res.json(); detail = `${p.title}: ${p.detail}`; } catch (e) { /* */ }
      throw new Error(detail);
    }
    return accept === "json" ? res.json() : res.blob();
  } finally {
    setBusy(-1);
  }
}

// -- controls -------------------------------------------------------------------------------

const INTEGER = new Set(["n", "gate"]);

function paramControl(name, value) {
  const row = document.createElement("label");
  row.className = "param";
  const input = document.createElement("input");
  input.id = `param-${name}`;
  input.name = name;
  if (name.startsWith("side")) { // an assembly choice: +1 or -1
    input.type = "range"; input.min = -1; input.max = 1; input.step = 2;
  } else if (INTEGER.has(name)) {
    input.type = "range"; input.min = 1; input.max = Math.max(20, 2 * value); input.step = 1;
  } else if (name === "theta" || name === "phi") {
    input.type = "range"; input.min = 0; input.max = TAU.toFixed(3); input.step = 0.01;
  } else {
    input.type = "range"; input.min = (0.2 * value).toFixed(3);
    input.max = (2.5 * value).toFixed(3); input.step = 0.005;
  }
  input.value = value;
  const out = document.createElement("output");
  out.textContent = Number(value).toFixed(3).replace(/\.?0+$/, "");
  input.addEventListener("input", () => {
    out.textContent = Number(input.value).toFixed(3).replace(/\.?0+$/, "");
  });
  input.addEventListener("change", loadPreset);
  const span = document.createElement("span");
  span.textContent = name;
  row.append(span, input, out);
  return row;
}

function showParams() {
  const preset = state.presets.find((p) => p.name === $("preset").value);
  const box = $("params");
  box.replaceChildren(...Object.entries(preset.parameters).map(([k, v]) => paramControl(k, v)));
  boundGate();
}

// The service takes 0 <= gate < n only (the presets' OpenAPI parameters say so): the gate
// slider follows the n slider, so that it never offers a gate the service refuses.
function boundGate() {
  const n = $("param-n"), gate = $("param-gate");
  if (!n || !gate) return;
  const follow = () => {
    gate.min = 0;
    gate.max = Math.max(0, Number(n.value) - 1);
    if (Number(gate.value) > Number(gate.max)) gate.value = gate.max;
    gate.dispatchEvent(new Event("input")); // its shown value
  };
  n.addEventListener("input", follow);
  follow();
}

async function loadPreset() {
  const name = $("preset").value;
  const query = new URLSearchParams();
  for (const input of $("params").querySelectorAll("input")) query.set(input.name, input.value);
  try {
    const linkage = await call(`v1/presets/${encodeURIComponent(name)}?${query}`);
    $("linkage-json").value = JSON.stringify(linkage, null, 1);
    await useLinkage(linkage);
  } catch (err) {
    status(`preset ${name}: ${err.message}`, true);
  }
}

function pinned(v, dim) {
  return v.fixed === true || (Array.isArray(v.fixed) && v.fixed.length === dim &&
                              v.fixed.every(Boolean));
}

function rotorsOf(linkage) {
  const pins = new Set(linkage.vertices.filter((v) => pinned(v, linkage.dimension || 2))
                                      .map((v) => v.id));
  return linkage.bars.filter((b) => pins.has(b.ends[0]) !== pins.has(b.ends[1])).map((b) => ({
    bar: b.id, pin: pins.has(b.ends[0]) ? b.ends[0] : b.ends[1],
    tip: pins.has(b.ends[0]) ? b.ends[1] : b.ends[0],
  }));
}

function barLength(linkage, bar) {
  if (bar.length) return bar.length;
  const pos = Object.fromEntries(linkage.vertices.map((v) => [v.id, v.position]));
  const [p, q] = [pos[bar.ends[0]], pos[bar.ends[1]]];
  return Math.hypot(...p.map((x, i) => x - q[i]));
}

function sliceAxes(linkage) {
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

async function useLinkage(linkage) {
  const generation = ++state.generation;
  stopAnimation();
  state.linkage = linkage;
  state.rotors = rotorsOf(linkage);
  state.space = null;
  state.at = null;
  sliceAxes(linkage);
  drawLinkage();
  drawSpace();
  status("computing the configuration space…");
  const space = call("v1/analysis/configuration-space", { linkage }).then((answer) => {
    if (generation !== state.generation) return;
    state.space = answer;
    state.at = nearestPoint(answer, linkage);
    $("animate").disabled = !state.at;
    drawSpace();
    drawLinkage();
    const n = answer.components.length;
    const m = answer.critical_points.length;
    $("space-caption").textContent = `${n} component${n === 1 ? "" : "s"}, ` +
      `${m} critical point${m === 1 ? "" : "s"}`;
  });
  const slice = drawSlice(generation);
  try {
    await Promise.all([space, slice]);
    if (generation === state.generation) status("ready");
  } catch (err) {
    if (generation === state.generation) status(err.message, true);
  }
}

async function drawSlice(generation) {
  const linkage = state.linkage;
  const [x, y] = [$("axis-x").value, $("axis-y").value];
  const el = $("slice");
  if (!x || !y || x === y) {
    el.textContent = "choose two different bars";
    return;
  }
  const bars = Object.fromEntries(linkage.bars.map((b) => [b.id, b]));
  const factor = Math.max(1.1, Number($("axis-range").value) || 2.5);
  const axes = [x, y].map((id) => {
    const len = barLength(linkage, bars[id]);
    return { bar: id, min: len / factor, max: len * factor };
  });
  $("slice-caption").textContent = `${x} × ${y}: computing…`;
  let blob;
  try {
    blob = await call("v1/figures/critical-values", { linkage, axes }, "blob");
  } catch (err) {
    if (generation === state.generation) {
      $("slice-caption").textContent = `${x} × ${y}: no slice`;
      el.textContent = err.message;
    }
    throw err;
  }
  if (generation !== state.generation) return;
  const img = new Image();
  img.alt = `critical values in the lengths of ${x} and ${y}`;
  img.src = URL.createObjectURL(blob);
  el.replaceChildren(img);
  el.dataset.draws = String(Number(el.dataset.draws) + 1);
  $("slice-caption").textContent = `${x} × ${y}; the star marks the linkage's lengths`;
}

// -- drawing ----------------------------------------------------------------------------------

function currentPositions() {
  const { space, at, linkage } = state;
  if (space && at) {
    const comp = space.components[at.component];
    return Object.fromEntries(Object.entries(comp.positions).map(([v, walk]) =>
      [v, walk[at.index]]));
  }
  return Object.fromEntries(linkage.vertices.map((v) => [v.id, v.position]));
}

function fit(ctx, points, pad = 30) {
  const xs = points.map((p) => p[0]);
  const ys = points.map((p) => p[1]);
  const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  const w = ctx.canvas.width - 2 * pad;
  const h = ctx.canvas.height - 2 * pad;
  const s = Math.min(w / Math.max(x1 - x0, 1e-9), h / Math.max(y1 - y0, 1e-9));
  const cx = (x0 + x1) / 2;
  const cy = (y0 + y1) / 2;
  return (p) => [ctx.canvas.width / 2 + s * (p[0] - cx), ctx.canvas.height / 2 - s * (p[1] - cy)];
}

function nearestPoint(space, linkage) {
  // Start where the linkage is: the point of the answer closest to the given positions.
  let best = null;
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

function drawLinkage() {
  const canvas = $("linkage");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const { linkage, space } = state;
  if (!linkage) return;
  const pos = currentPositions();
  // A view that holds the whole motion, so that it does not jump while animating.
  let extent = Object.values(pos);
  if (space && state.at) {
    const comp = space.components[state.at.component];
    extent = extent.concat(...Object.values(comp.positions).map((w) =>
      w.filter((_, i) => i % 4 === 0)));
  }
  const map = fit(ctx, extent);
  ctx.lineCap = "round";
  for (const bar of linkage.bars) {
    const [p, q] = bar.ends.map((v) => map(pos[v]));
    ctx.strokeStyle = "#555"; ctx.lineWidth = 4;
    ctx.beginPath(); ctx.moveTo(...p); ctx.lineTo(...q); ctx.stroke();
    ctx.fillStyle = "#345"; ctx.font = "12px sans-serif";
    ctx.fillText(bar.id, (p[0] + q[0]) / 2 + 5, (p[1] + q[1]) / 2 - 5);
  }
  for (const v of linkage.vertices) {
    const [x, y] = map(pos[v.id]);
    ctx.beginPath();
    if (pinned(v, linkage.dimension || 2)) {
      ctx.moveTo(x, y - 8); ctx.lineTo(x + 8, y + 6); ctx.lineTo(x - 8, y + 6); ctx.closePath();
      ctx.fillStyle = "#111"; ctx.fill();
    } else if (Array.isArray(v.fixed) && v.fixed.some(Boolean)) {
      ctx.rect(x - 6, y - 6, 12, 12); ctx.fillStyle = "#9467bd"; ctx.fill();
    } else {
      ctx.arc(x, y, 5, 0, TAU); ctx.fillStyle = "#fff"; ctx.fill();
      ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5; ctx.stroke();
    }
    ctx.fillStyle = "#111"; ctx.font = "11px sans-serif";
    ctx.fillText(v.id, x - 14, y + 18);
  }
  const at = state.at;
  $("linkage-caption").textContent = at
    ? `component ${at.component}, point ${at.index}` : "as given";
}

const wrap = (a) => ((a + Math.PI) % TAU + TAU) % TAU - Math.PI;

function spaceAxes() {
  const comp = state.space && state.space.components[0];
  const bars = comp ? Object.keys(comp.angles) : state.rotors.map((r) => r.bar);
  return bars.slice(0, 2);
}

function spaceMap(canvas) {
  const pad = 40;
  const s = Math.min(canvas.width - 2 * pad, canvas.height - 2 * pad) / TAU;
  const ox = pad + s * Math.PI;
  const oy = canvas.height - pad - s * Math.PI;
  return { s, to: (a, b) => [ox + s * a, oy - s * b], from: (x, y) => [(x - ox) / s, (oy - y) / s] };
}

function drawSpace() {
  const canvas = $("space");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const axes = spaceAxes();
  const { to } = spaceMap(canvas);
  // the square of the torus, with axis labels
  const [x0, y0] = to(-Math.PI, Math.PI);
  const [x1, y1] = to(Math.PI, -Math.PI);
  ctx.strokeStyle = "#aaa"; ctx.lineWidth = 1; ctx.strokeRect(x0, y0, x1 - x0, y1 - y0);
  ctx.fillStyle = "#333"; ctx.font = "12px sans-serif";
  ctx.fillText(axes[0] ? `angle of ${axes[0]}` : "", (x0 + x1) / 2 - 30, y1 + 28);
  ctx.fillText("−π", x0 - 8, y1 + 14); ctx.fillText("π", x1 - 4, y1 + 14);
  ctx.save(); ctx.translate(x0 - 14, (y0 + y1) / 2 + 30); ctx.rotate(-Math.PI / 2);
  ctx.fillText(axes[1] ? `angle of ${axes[1]}` : "", 0, 0); ctx.restore();
  const space = state.space;
  if (!space) {
    ctx.fillText(state.linkage ? "computing…" : "", (x0 + x1) / 2 - 30, (y0 + y1) / 2);
    return;
  }
  if (axes.length < 2) {
    ctx.fillText("needs two rotors (bars with one pinned end)", x0 + 10, (y0 + y1) / 2);
  } else {
    space.components.forEach((comp, k) => {
      const a = comp.angles[axes[0]].map(wrap);
      const b = comp.angles[axes[1]].map(wrap);
      ctx.strokeStyle = COLOURS[k % COLOURS.length]; ctx.lineWidth = 2;
      ctx.beginPath();
      a.forEach((_, i) => {
        const p = to(a[i], b[i]);
        const jump = i > 0 && (Math.abs(a[i] - a[i - 1]) > Math.PI ||
                               Math.abs(b[i] - b[i - 1]) > Math.PI);
        if (i === 0 || jump) ctx.moveTo(...p); else ctx.lineTo(...p);
      });
      ctx.stroke();
    });
    const rotor = Object.fromEntries(state.rotors.map((r) => [r.bar, r]));
    for (const cp of space.critical_points) {
      const ang = axes.map((bar) => {
        const r = rotor[bar];
        const p = cp.configuration[r.pin];
        const q = cp.configuration[r.tip];
        return Math.atan2(q[1] - p[1], q[0] - p[0]);
      });
      const [x, y] = to(...ang);
      ctx.strokeStyle = KINDS[cp.kind] || "#777"; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.moveTo(x - 6, y - 6); ctx.lineTo(x + 6, y + 6);
      ctx.moveTo(x + 6, y - 6); ctx.lineTo(x - 6, y + 6); ctx.stroke();
    }
    if (state.at) {
      const comp = space.components[state.at.component];
      const [x, y] = to(wrap(comp.angles[axes[0]][state.at.index]),
                        wrap(comp.angles[axes[1]][state.at.index]));
      ctx.fillStyle = "#ffd92f"; ctx.strokeStyle = "#111"; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.arc(x, y, 6, 0, TAU); ctx.fill(); ctx.stroke();
    }
  }
  canvas.dataset.components = String(space.components.length);
  canvas.dataset.criticalPoints = String(space.critical_points.length);
  canvas.dataset.points = String(space.components.reduce(
    (n, c) => n + (Object.values(c.angles)[0] || []).length, 0));
  canvas.dataset.lengths = state.linkage.bars.map((b) => barLength(state.linkage, b).toFixed(4))
    .join(",");
  canvas.dataset.draws = String(Number(canvas.dataset.draws) + 1);
}

function pick(event) {
  const space = state.space;
  const axes = spaceAxes();
  if (!space || axes.length < 2) return;
  const canvas = $("space");
  const rect = canvas.getBoundingClientRect();
  const x = (event.clientX - rect.left) * canvas.width / rect.width;
  const y = (event.clientY - rect.top) * canvas.height / rect.height;
  const [a, b] = spaceMap(canvas).from(x, y);
  let best = null;
  space.components.forEach((comp, k) => {
    comp.angles[axes[0]].forEach((ang, i) => {
      const da = wrap(wrap(ang) - a);
      const db = wrap(wrap(comp.angles[axes[1]][i]) - b);
      const d = da * da + db * db;
      if (!best || d < best.d) best = { d, component: k, index: i };
    });
  });
  if (best) {
    stopAnimation();
    state.at = { component: best.component, index: best.index };
    drawSpace();
    drawLinkage();
  }
}

// -- animation --------------------------------------------------------------------------------

function stopAnimation() {
  if (state.animation) cancelAnimationFrame(state.animation);
  state.animation = null;
  $("animate").textContent = "Animate along the component";
}

function animate() {
  if (state.animation) { stopAnimation(); return; }
  $("animate").textContent = "Stop";
  let last = 0;
  const step = (time) => {
    if (time - last > 30 && state.space && state.at) {
      last = time;
      const comp = state.space.components[state.at.component];
      const n = Object.values(comp.angles)[0].length;
      state.at = { component: state.at.component,
                   index: comp.closed ? (state.at.index + 1) % n
                     : (state.at.index + 1 < n ? state.at.index + 1 : 0) };
      drawLinkage();
      drawSpace();
    }
    state.animation = requestAnimationFrame(step);
  };
  state.animation = requestAnimationFrame(step);
}

// -- figures from the service ---------------------------------------------------------------

async function showFigure(kind) {
  if (!state.linkage) return;
  const body = kind === "linkage"
    ? { linkage: { ...state.linkage, vertices: state.linkage.vertices.map((v) =>
        ({ ...v, position: currentPositions()[v.id] })) }, show: ["zero_modes"] }
    : { linkage: state.linkage };
  try {
    const blob = await call(`v1/figures/${kind}`, body, "blob");
    const img = new Image();
    img.src = URL.createObjectURL(blob);
    img.alt = `${kind} figure`;
    $("figure-body").replaceChildren(img);
    $("figure-dialog").showModal();
  } catch (err) {
    status(`${kind} figure: ${err.message}`, true);
  }
}

// -- start ------------------------------------------------------------------------------------

async function start() {
  $("preset").addEventListener("change", () => {
    if (!$("preset").value) return;
    showParams();
    loadPreset();
  });
  $("use-linkage").addEventListener("click", () => {
    let linkage;
    try {
      linkage = JSON.parse($("linkage-json").value);
    } catch (err) {
      status(`not JSON: ${err.message}`, true);
      return;
    }
    useLinkage(linkage.linkage || linkage);
  });
  for (const id of ["axis-x", "axis-y", "axis-range"]) {
    $(id).addEventListener("change", () => {
      if (state.linkage) drawSlice(state.generation).catch((e) => status(e.message, true));
    });
  }
  $("space").addEventListener("click", pick);
  $("animate").addEventListener("click", animate);
  for (const button of document.querySelectorAll("[data-figure]")) {
    button.addEventListener("click", () => showFigure(button.dataset.figure));
  }
  try {
    state.presets = await call("v1/presets");
  } catch (err) {
    status(`presets: ${err.message}`, true);
    return;
  }
  $("preset").replaceChildren(new Option("choose a preset…", ""),
                              ...state.presets.map((p) => new Option(p.name, p.name)));
  const wanted = new URLSearchParams(window.location.search).get("preset");
  if (state.presets.some((p) => p.name === wanted)) {
    $("preset").value = wanted;
    showParams();
    await loadPreset();
  } else {
    status("choose a preset or paste a linkage");
  }
}

start();
