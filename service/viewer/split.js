// The splitting panel: perturb the lengths of a linkage at critical lengths (or ask the service's
// design for a sign per branch point), see the perturbed configuration space overlaid on the
// critical one, and the prediction checked against the re-trace.
"use strict";

const splitView = { perturbed: null, rows: [], kind: "" };

function median(xs) {
  const s = xs.slice().sort((a, b) => a - b);
  return s.length ? s[Math.floor(s.length / 2)] : 1;
}

function freeBars(linkage) {
  const pins = new Set(linkage.vertices.filter((v) => pinned(v, linkage.dimension || 2))
                                      .map((v) => v.id));
  return linkage.bars.filter((b) => !(pins.has(b.ends[0]) && pins.has(b.ends[1])));
}

/** The panel's controls for the linkage shown: a bar and its length change, and a target sign
 * per branch point of the configuration space. */
function splitControls() {
  const linkage = state.drawable ? state.linkage : null;
  const answer = state.space;
  const branch = answer ? answer.critical_points.filter((c) => c.kind === "branch") : [];
  const bars = linkage ? freeBars(linkage) : [];
  const keep = $("split-bar").value;
  $("split-bar").replaceChildren(...bars.map((b) => new Option(b.id, b.id)));
  if (bars.some((b) => b.id === keep)) $("split-bar").value = keep;
  else if (bars.length) $("split-bar").value = bars[Math.min(1, bars.length - 1)].id;
  if (linkage) {
    const h = 0.02 * median(linkage.bars.map((b) => barLength(linkage, b)));
    $("split-dl").value = String(Number(h.toPrecision(2)));
  }
  $("design-targets").replaceChildren(...branch.map((cp) => {
    const label = document.createElement("label");
    label.textContent = `#${cp.index} `;
    const sel = document.createElement("select");
    sel.dataset.branchPoint = String(cp.index);
    sel.append(new Option("sign +1", "1"), new Option("sign −1", "-1"));
    label.append(sel);
    return label;
  }));
  const ready = branch.length > 0;
  $("split-run").disabled = !ready;
  $("design-run").disabled = !ready;
  $("split-caption").textContent = !answer ? "" : (ready
    ? `${branch.length} branch point${branch.length === 1 ? "" : "s"}: perturb to split them`
    : "no branch point here: move the lengths onto a critical value (the map's curves)");
}

/** Which rays the perturbed space joins near a branch point: each piece of a perturbed curve
 * inside a ball around the critical configuration enters along one ray and leaves along
 * another (the nearest of +t0, -t0, +t1, -t1 to where it crosses the ball). */
function tracedConnects(perturbed, cp, others, ids) {
  const c = flat(cp.configuration, ids);
  const rays = (cp.tangents || []).flatMap((t) => {
    const v = flat(t, ids);
    return [v, v.map((x) => -x)];
  });
  const gaps = others.map((o) => Math.hypot(...flat(o.configuration, ids).map((x, i) =>
    x - c[i])));
  const scale = median(state.linkage.bars.map((b) => barLength(state.linkage, b)));
  const radius = 0.3 * Math.min(scale * 2, ...gaps);
  const rayOf = (u) => {
    const d = u.map((x, i) => x - c[i]);
    let best = 0;
    rays.forEach((r, k) => {
      const dot = r.reduce((s, x, i) => s + x * d[i], 0);
      if (dot > rays[best].reduce((s, x, i) => s + x * d[i], 0)) best = k;
    });
    return best;
  };
  const pairs = new Set();
  for (const comp of perturbed.components) {
    const n = Object.values(comp.positions)[0].length;
    let walk = Array.from({ length: n }, (_, i) => ids.flatMap((id) => comp.positions[id][i]));
    const inside = (u) => Math.hypot(...u.map((x, i) => x - c[i])) < radius;
    if (comp.closed) { // start outside the ball, so that no piece is cut in two
      const out = walk.findIndex((u) => !inside(u));
      if (out < 0) continue;
      walk = walk.slice(out, n - 1).concat(walk.slice(0, out + 1));
    }
    let entry = null;
    walk.forEach((u, i) => {
      if (inside(u) && entry === null && i > 0) entry = i;
      if (!inside(u) && entry !== null) {
        const pair = [rayOf(walk[entry]), rayOf(walk[i - 1])].sort();
        if (pair[0] !== pair[1]) pairs.add(JSON.stringify(pair));
        entry = null;
      }
    });
  }
  return [...pairs].map((p) => JSON.parse(p)).sort();
}

const pairsText = (pairs) => (pairs ? pairs.map((p) => `${p[0]}–${p[1]}`).join(", ") : "—");
const samePairs = (a, b) => JSON.stringify(a.map((p) => p.slice().sort()).sort()) ===
  JSON.stringify(b.map((p) => p.slice().sort()).sort());

function drawSplit() {
  const canvas = $("split");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const axes = spaceAxes();
  const map = spaceMap(canvas);
  plotFrame(ctx, map, axes);
  if (!state.space || axes.length < 2) return;
  plotComponents(ctx, map, state.space, axes, { colour: "#999", width: 4 });
  if (splitView.perturbed) plotComponents(ctx, map, splitView.perturbed, axes, { width: 1.5 });
  plotCritical(ctx, map, state.space, axes);
  canvas.dataset.perturbedComponents = splitView.perturbed
    ? String(splitView.perturbed.components.length) : "";
}

function showSplitRows() {
  const table = $("split-table");
  const head = document.createElement("tr");
  for (const h of ["branch point", "Δ", "sign", "predicted joins", "re-traced joins", "agree"]) {
    const th = document.createElement("th");
    th.textContent = h;
    head.append(th);
  }
  table.replaceChildren(head, ...splitView.rows.map((r) => {
    const tr = document.createElement("tr");
    tr.dataset.branchPoint = String(r.index);
    tr.dataset.agree = String(r.agree);
    for (const cell of [`#${r.index}`, fmt(r.delta), r.sign > 0 ? "+1" : "−1",
                        pairsText(r.connects), pairsText(r.traced),
                        r.agree === null ? "not checked" : (r.agree ? "yes" : "NO")]) {
      const td = document.createElement("td");
      td.textContent = cell;
      tr.append(td);
    }
    return tr;
  }));
}

/** Trace the perturbed linkage and check each prediction against it. */
async function retrace(generation, lengths, predicted, checkedBy) {
  const linkage = withLengths(state.linkage, lengths);
  const perturbed = await call("v1/analysis/configuration-space", { linkage },
                               { task: "re-trace", generation });
  if (generation !== state.generation) return;
  hingeAngles(perturbed); // (3D answers carry no angles)
  splitView.perturbed = perturbed;
  const ids = state.linkage.vertices.map((v) => v.id);
  const crit = state.space.critical_points;
  splitView.rows = predicted.map((p) => {
    const cp = crit.find((c) => c.index === p.index);
    const traced = p.traced || (cp ? tracedConnects(perturbed, cp,
                                                    crit.filter((c) => c !== cp), ids) : null);
    return { ...p, traced, agree: traced ? samePairs(p.connects, traced) : null };
  });
  const agree = splitView.rows.every((r) => r.agree);
  $("split-verdict").textContent = `${splitView.rows.length} predictions, ` +
    `${splitView.rows.filter((r) => r.agree).length} confirmed by the re-trace ` +
    `(${checkedBy}); the perturbed space has ${perturbed.components.length} ` +
    `component${perturbed.components.length === 1 ? "" : "s"}` + (agree ? "" : ": CHECK FAILED");
  $("split").dataset.verified = String(agree);
  showSplitRows();
  drawSplit();
}

async function runSplitting() {
  const generation = state.generation;
  const bar = $("split-bar").value;
  const dl = Number($("split-dl").value);
  if (!bar || !Number.isFinite(dl) || dl === 0) {
    $("split-verdict").textContent = "choose a bar and a length change other than 0";
    return;
  }
  const linkage = state.linkage;
  try {
    const answer = await call("v1/analysis/splitting", { linkage, perturbation: { [bar]: dl } },
                              { task: "splitting", generation });
    if (generation !== state.generation) return;
    const current = barLength(linkage, linkage.bars.find((b) => b.id === bar));
    const predicted = answer.branch_points.map((b) => ({
      index: b.index, delta: b.delta, sign: b.sign, connects: b.connects,
      traced: b.traced_connects || null }));
    $("split-perturbation").textContent = `${bar} ${dl > 0 ? "+" : "−"}${fmt(Math.abs(dl))}`;
    await retrace(generation, { [bar]: current + dl }, predicted, "rays read off the re-traced " +
                  "curves by the viewer");
  } catch (err) { /* the status line says it */ }
}

async function runDesign() {
  const generation = state.generation;
  const linkage = state.linkage;
  const targets = [...$("design-targets").querySelectorAll("select")].map((s) => ({
    branch_point: Number(s.dataset.branchPoint), sign: Number(s.value) }));
  const adjustable = freeBars(linkage).map((b) => b.id);
  try {
    const answer = await call("v1/design/splitting", { linkage, targets, adjustable },
                              { task: "design", generation });
    if (generation !== state.generation) return;
    if (!answer.feasible) {
      $("split-verdict").textContent = "no perturbation gives these signs: " +
        answer.conflicts.map((c) => `${c.branch_points.join(", ")}: ${c.reason}`).join("; ");
      splitView.rows = []; splitView.perturbed = null;
      showSplitRows(); drawSplit();
      return;
    }
    const lengths = Object.fromEntries(Object.entries(answer.perturbation).map(([b, d]) =>
      [b, barLength(linkage, linkage.bars.find((x) => x.id === b)) + d]));
    $("split-perturbation").textContent = Object.entries(answer.perturbation)
      .filter(([, d]) => d !== 0).map(([b, d]) => `${b} ${d > 0 ? "+" : "−"}${fmt(Math.abs(d))}`)
      .join(", ") + ` (service verified: ${answer.verified})`;
    const predicted = answer.predicted.map((p) => ({
      index: p.branch_point, delta: p.delta, sign: p.sign, connects: p.connects,
      traced: p.traced_connects || null }));
    await retrace(generation, lengths, predicted, "the service's re-trace");
  } catch (err) { /* the status line says it */ }
}

function startSplitting() {
  $("split-run").addEventListener("click", runSplitting);
  $("design-run").addEventListener("click", runDesign);
  state.listeners.push((generation, what) => {
    if (what === "at") return;
    splitView.perturbed = null;
    splitView.rows = [];
    $("split-verdict").textContent = "";
    $("split-perturbation").textContent = "";
    delete $("split").dataset.verified;
    splitControls();
    showSplitRows();
    drawSplit();
  });
  for (const id of ["space-x", "space-y"]) $(id).addEventListener("change", drawSplit);
}
