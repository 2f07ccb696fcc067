// The linkage viewer: calls the service's public JSON and figure endpoints only. This file holds
// the state, the requests and the linkage drawing (drag a joint or a bar); space.js, map.js,
// split.js and view3d.js draw the other panels from the same state.
"use strict";

const API = new URL("..", window.location.href); // the service root (the viewer is /viewer/)
const TAU = 2 * Math.PI;
const COLOURS = ["#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf",
                 "#bcbd22", "#7f7f7f"];
const KINDS = { branch: "#d62728", rigid: "#111111", degenerate: "#b34700" };
const DEBOUNCE_MS = 60; // between the last move of a drag and the request it makes
const REFINE_AFTER_MS = 400; // then, without a new move, quick answers are asked again in full
const $ = (id) => document.getElementById(id);

const state = {
  presets: [],
  source: "", // what the linkage is: a preset's name, "pasted", or "<preset>, edited"
  linkage: null, // the linkage being looked at (as the API gives it)
  space: null, // the answer of /v1/analysis/configuration-space
  rotors: [], // [{bar, pin, tip}] bars with exactly one pinned end
  at: null, // {component, index}: the configuration shown
  generation: 0, // answers of older requests are dropped
  animation: null,
  tasks: new Map(), // name -> {state: "pending" | "done" | "error", message}
  controllers: new Map(), // name -> the AbortController of its request in flight
  listeners: [], // functions (generation) called when a new linkage is shown
  changed: 0, // performance.now() of the last change of the linkage (drag, slider, paste)
};

/** The linkage changed (a drag, a slider, a paste, a region): the latencies count from here. */
function markChange() {
  state.changed = performance.now();
  delete $("map").dataset.usefulMs;
}

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

/** The status line follows the tasks of the linkage shown: the first error, else what is still
 * computing, else ready. */
function showTasks() {
  const tasks = [...state.tasks.entries()];
  const failed = tasks.find(([, t]) => t.state === "error");
  if (failed) { status(`${failed[0]}: ${failed[1].message}`, true); return; }
  const pending = tasks.filter(([, t]) => t.state === "pending").map(([name]) => name);
  if (pending.length) status(`computing ${pending.join(", ")}…`);
  else status(state.linkage ? "ready" : "choose a preset or paste a linkage");
}

/** A problem+json (RFC 9457) or any other failed answer as one readable line. */
async function problemText(res) {
  const head = `${res.status} ${res.statusText || ""}`.trim();
  let body = "";
  try { body = await res.text(); } catch (e) { return head; }
  try {
    const p = JSON.parse(body);
    const parts = [p.title, p.detail].filter((s) => typeof s === "string" && s);
    const where = Array.isArray(p.errors)
      ? p.errors.map((e) => `${(e.loc || []).join(".")}: ${e.msg}`).filter((s) => s) : [];
    const text = parts.join(": ") + (where.length && !parts.join("").includes(where[0])
      ? ` (${where.join("; ")})` : "");
    return text ? `${text} [${p.status || res.status}]` : head;
  } catch (e) {
    return body.trim() ? `${head}: ${body.trim().slice(0, 200)}` : head;
  }
}

/** One request to the service: the answer, or an Error whose message is the problem's title and
 * detail (any 4xx or 5xx). */
async function request(path, body, accept, signal) {
  const init = body === undefined ? { signal } : {
    method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify(body), signal,
  };
  setBusy(1);
  try {
    const res = await fetch(new URL(path, API), init);
    if (!res.ok) throw new Error(await problemText(res));
    return await (accept === "json" ? res.json() : res.blob());
  } catch (err) {
    if (err.name === "AbortError") err.superseded = true;
    throw err;
  } finally {
    setBusy(-1);
  }
}

/** A named task of the linkage shown: it replaces the task of that name still in flight (which
 * is aborted) and its progress shows in the status line. `work(signal)` does the requests. */
async function runTask(task, generation, work) {
  const controller = new AbortController();
  const old = state.controllers.get(task);
  if (old) old.abort();
  state.controllers.set(task, controller);
  state.tasks.set(task, { state: "pending" });
  showTasks();
  const current = () => state.controllers.get(task) === controller &&
    (generation === null || generation === state.generation);
  try {
    const answer = await work(controller.signal);
    if (current()) { state.tasks.set(task, { state: "done" }); showTasks(); }
    if (controller.signal.aborted) {
      const e = new Error("superseded");
      e.superseded = true;
      throw e;
    }
    return answer;
  } catch (err) {
    if (err.name === "AbortError" || controller.signal.aborted) err.superseded = true;
    else if (current()) {
      state.tasks.set(task, { state: "error", message: err.message });
      showTasks();
    }
    throw err;
  } finally {
    if (state.controllers.get(task) === controller) state.controllers.delete(task);
  }
}

/** POST (with a body) or GET a path of the service as a task (see runTask). */
function call(path, body, { accept = "json", task = "request", generation = null } = {}) {
  return runTask(task, generation, (signal) => request(path, body, accept, signal));
}

/** Abort every request in flight (a new linkage supersedes them all). */
function abortAll() {
  for (const c of state.controllers.values()) c.abort();
  state.controllers.clear();
  state.tasks.clear();
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
  if (!preset) { box.replaceChildren(); return; }
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

/** The preset's sliders no longer describe the linkage (pasted, or edited on the drawing). */
function forgetParams(note) {
  $("preset").value = "";
  const p = document.createElement("p");
  p.className = "hint";
  p.id = "params-note";
  p.textContent = note;
  $("params").replaceChildren(p);
}

async function loadPreset() {
  const name = $("preset").value;
  if (!name) return;
  const query = new URLSearchParams();
  for (const input of $("params").querySelectorAll("input")) query.set(input.name, input.value);
  const generation = ++state.generation;
  abortAll();
  markChange();
  try {
    const linkage = await call(`v1/presets/${encodeURIComponent(name)}?${query}`, undefined,
                               { task: "preset", generation });
    if (generation !== state.generation) return;
    $("linkage-json").value = JSON.stringify(linkage, null, 1);
    useLinkage(linkage, name);
  } catch (err) {
    if (err.superseded || generation !== state.generation) return;
    showNothing(`preset ${name}: no linkage`);
  }
}

/** After a failed request for the linkage itself: no drawing of the previous one stays. */
function showNothing(caption) {
  stopAnimation();
  state.linkage = null;
  state.drawable = false;
  state.space = null;
  state.at = null;
  state.source = "";
  $("linkage-caption").textContent = caption;
  $("space-caption").textContent = "no configuration space";
  for (const f of state.listeners) f(state.generation, "cleared");
  drawLinkage();
  drawSpace();
}

function pinned(v, dim) {
  return v.fixed === true || (Array.isArray(v.fixed) && v.fixed.length === dim &&
                              v.fixed.every(Boolean));
}

/** The rotors of a linkage, each with one angle: in the plane a bar with exactly one pinned end
 * (named by the bar); in 3D a hinge, a free vertex joined by bars to exactly two pins (named
 * by the vertex: its angle about the axis through the two pins, which the service's answers do
 * not carry: see hingeAngles). */
function rotorsOf(linkage) {
  const pins = new Set(linkage.vertices.filter((v) => pinned(v, linkage.dimension || 2))
                                      .map((v) => v.id));
  if ((linkage.dimension || 2) === 3) {
    return linkage.vertices.filter((v) => !pins.has(v.id)).map((v) => ({
      tip: v.id, hinge: true,
      pins: linkage.bars.filter((b) => b.ends.includes(v.id))
        .map((b) => (b.ends[0] === v.id ? b.ends[1] : b.ends[0])).filter((u) => pins.has(u)),
    })).filter((r) => r.pins.length === 2).map((r) => ({
      bar: r.tip, pin: r.pins[0], pin2: r.pins[1], tip: r.tip, hinge: true }));
  }
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

/** A copy of the linkage with some bars' lengths changed ({bar_id: length}); the positions stay
 * and the service projects them onto the new lengths. */
function withLengths(linkage, lengths) {
  return { ...linkage, bars: linkage.bars.map((b) => (b.id in lengths
    ? { ...b, length: lengths[b.id] } : { ...b, length: barLength(linkage, b) })) };
}

/** Show a linkage: the drawing at once, then the configuration space (and, through the
 * listeners, the map, the margin and the other panels), each request replacing its older one. */
function useLinkage(linkage, source, quick = false) {
  const generation = ++state.generation;
  state.quick = quick; // a drag: the map's searches get a short budget first
  stopAnimation();
  for (const [name, c] of state.controllers) if (name !== "preset") c.abort();
  state.tasks.clear();
  state.linkage = linkage;
  state.source = source;
  state.space = null;
  state.at = null;
  $("space-caption").textContent = "computing…";
  $("animate").disabled = true;
  // A linkage the viewer cannot draw (a pasted one with a bar to nowhere, say) is still sent:
  // the service's answer names what is wrong with it.
  state.drawable = drawable(linkage);
  state.rotors = state.drawable ? rotorsOf(linkage) : [];
  if (state.drawable) {
    drawLinkage();
    spaceAxesChoice(linkage);
    for (const f of state.listeners) f(generation, "linkage");
  } else {
    for (const f of state.listeners) f(generation, "cleared");
    drawLinkage();
    $("linkage-caption").textContent = `${source}: cannot be drawn as given`;
  }
  drawSpace();
  // While a drag goes on the search skips the homotopy that proves it complete (about half of a
  // three-rotor's search); the full search follows once the hand rests (refineSpace).
  const body = quick ? { linkage, options: { homotopy_paths_max: 0 } } : { linkage };
  call("v1/analysis/configuration-space", body, { task: "configuration space", generation })
    .then((answer) => {
      if (generation !== state.generation) return;
      if (!state.drawable) return;
      showSpace(answer, linkage, quick);
      $("space").dataset.latencyMs = String(Math.round(performance.now() - state.changed));
      for (const f of state.listeners) f(generation, "space");
      if (quick) {
        setTimeout(() => { if (generation === state.generation) refineSpace(generation); },
                   REFINE_AFTER_MS);
      }
    })
    .catch((err) => {
      if (err.superseded || generation !== state.generation) return;
      $("space-caption").textContent = "no configuration space (see the status line)";
      drawSpace(err.message);
      for (const f of state.listeners) f(generation, "space-failed");
    });
}

/** Whether the viewer can draw a linkage: vertices with positions, bars between them. */
function drawable(linkage) {
  if (!linkage || !Array.isArray(linkage.vertices) || !Array.isArray(linkage.bars)) return false;
  const dim = linkage.dimension || 2;
  const ids = new Set(linkage.vertices.map((v) => v && v.id));
  return linkage.vertices.every((v) => v && Array.isArray(v.position) &&
                                v.position.length === dim &&
                                v.position.every((x) => typeof x === "number")) &&
    linkage.bars.every((b) => b && Array.isArray(b.ends) && b.ends.length === 2 &&
                       b.ends.every((e) => ids.has(e)));
}

/** "3 components" when the search is complete; a bound when it was cut short or capped. */
function spaceCaption(answer) {
  const n = answer.components.length;
  const m = answer.critical_points.length;
  const search = answer.search || {};
  const total = search.components_total;
  const plural = (k, word) => `${k} ${word}${k === 1 ? "" : "s"}`;
  // a count beyond 2^53 - 1 comes as a decimal string
  const known = Number.isInteger(total) || (typeof total === "string" && /^\d+$/.test(total));
  let comps;
  if (known && BigInt(total) > BigInt(n)) {
    comps = `${n} of ${total} components traced (${total} by ${search.components_total_rule ||
      "the chain count"})`;
  } else if (known) {
    comps = plural(Number(total), "component");
  } else if (search.complete === false) {
    comps = `at least ${plural(n, "component")} (search cut short: ${search.reason})`;
  } else {
    comps = plural(n, "component");
  }
  const crit = search.complete === false && !known
    ? `at least ${plural(m, "critical point")}` : plural(m, "critical point");
  // a chain with the paper's gate: decided from the gate four-bar, not from what was traced
  const gate = !("gated" in search) ? ""
    : search.gated === null ? ", gate undecided" : search.gated ? ", gated" : ", ungated";
  return `${comps}, ${crit}${gate}`;
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
      moveAlong(1);
    }
    state.animation = requestAnimationFrame(step);
  };
  state.animation = requestAnimationFrame(step);
}

/** One step along the component shown (the arrow keys on the configuration space). */
function moveAlong(delta) {
  if (!state.space || !state.at || state.at.surface !== undefined) return;
  const comp = state.space.components[state.at.component];
  const n = Object.values(comp.angles)[0].length;
  state.at = { component: state.at.component, index: ((state.at.index + delta) % n + n) % n };
  showAt();
}

/** Redraw whatever depends on the configuration shown. */
function showAt() {
  drawLinkage();
  drawSpace();
  for (const f of state.listeners) f(state.generation, "at");
}

// -- figures from the service ---------------------------------------------------------------

async function showFigure(kind) {
  if (!state.linkage) return;
  let body;
  if (kind === "linkage") {
    body = { linkage: { ...state.linkage, vertices: state.linkage.vertices.map((v) =>
      ({ ...v, position: currentPositions()[v.id] })) }, show: ["zero_modes"] };
  } else if (kind === "critical-values") {
    body = mapRequest();
    if (!body) return;
  } else {
    body = { linkage: state.linkage };
  }
  try {
    const blob = await call(`v1/figures/${kind}`, body, { accept: "blob", task: `${kind} figure` });
    const img = new Image();
    img.src = URL.createObjectURL(blob);
    img.alt = `${kind} figure`;
    $("figure-body").replaceChildren(img);
    $("figure-dialog").showModal();
  } catch (err) { /* the status line says it */ }
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
      abortAll();
      state.tasks.set("pasted linkage", { state: "error", message: `not JSON: ${err.message}` });
      showTasks();
      return;
    }
    forgetParams("a pasted linkage: drag its joints and bars on the drawing");
    markChange();
    useLinkage(linkage.linkage || linkage, "pasted linkage");
  });
  const canvas = $("linkage");
  canvas.addEventListener("pointerdown", grab);
  canvas.addEventListener("pointermove", dragMove);
  canvas.addEventListener("pointerup", drop);
  canvas.addEventListener("pointercancel", drop);
  canvas.addEventListener("keydown", linkageKeys);
  canvas.addEventListener("focus", drawLinkage);
  canvas.addEventListener("blur", drawLinkage);
  $("animate").addEventListener("click", animate);
  for (const button of document.querySelectorAll("[data-figure]")) {
    button.addEventListener("click", () => showFigure(button.dataset.figure));
  }
  state.listeners.push((generation, what) => {
    // a drag's quick answer gets no readout: the refined one does (a worker stays free)
    if (what === "at" || what === "space-refined" || (what === "space" && !state.quick)) {
      loadReadout(generation);
    } else {
      $("readout").textContent = "";
    }
  });
  startSpace();
  startMap();
  startSplitting();
  start3d();
  try {
    state.presets = await call("v1/presets", undefined, { task: "presets" });
  } catch (err) {
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
    state.tasks.clear();
    showTasks();
  }
}

window.addEventListener("DOMContentLoaded", start);
