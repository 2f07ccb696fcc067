// Surfaces in the 3D view: a configuration space with two degrees of freedom comes from the
// service as triangulated surfaces (`surfaces`: each a mesh with the linkage's positions at every
// mesh vertex, its triangles and its topology; docs/API.md). Here each mesh is drawn in the three
// chosen coordinates with the 3D view's rotation and projection, its triangles filled back to
// front (the painter's order) and shaded by how they face the viewer; a click picks the nearest
// mesh vertex in front and loads the linkage at that configuration.
"use strict";

/** One coordinate of a surface at each mesh vertex: [values], and whether it is an angle. A
 * rotor angle is computed from the positions (a surface carries no angles). */
function surfaceCoordinate(surf, key) {
  const [kind, id, axis] = key.split(":");
  if (kind === "angle") {
    const rotor = rotorsByBar()[id];
    const ids = [rotor.pin, rotor.pin2, rotor.tip].filter((v) => v);
    return { values: surf.positions[rotor.tip].map((_, i) => rotorAngle(
      Object.fromEntries(ids.map((v) => [v, surf.positions[v][i]])), rotor)), angle: true };
  }
  return { values: surf.positions[id].map((p) => p[Number(axis)]), angle: false };
}

/** The 3D view's default coordinates for surfaces: two rotor angles (the torus they live over)
 * and a coordinate of a free vertex that is not a rotor's tip (it tells the sheets apart). */
function surfaceChoice(linkage, choices) {
  const tips = new Set(rotorsOf(linkage).map((r) => r.tip));
  const angles = choices.filter(([v]) => v.startsWith("angle:"));
  const free = choices.filter(([v]) => !v.startsWith("angle:") && !tips.has(v.split(":")[1]));
  const rest = choices.filter(([v]) => !angles.includes(v) && !free.includes(v));
  return [...angles.slice(0, 2), ...free, ...angles.slice(2), ...rest].slice(0, 3)
    .map(([v]) => v);
}

/** A one-line summary of a surface's topology as the service gives it. */
function surfaceText(surf, k) {
  const parts = [`surface ${k}: ${surf.closed ? "closed" : "open"}`];
  if (surf.genus !== null && surf.genus !== undefined) parts.push(`genus ${surf.genus}`);
  if (surf.euler !== null && surf.euler !== undefined) parts.push(`χ = ${surf.euler}`);
  if (surf.orientable !== null && surf.orientable !== undefined) {
    parts.push(surf.orientable ? "orientable" : "non-orientable");
  }
  if (Array.isArray(surf.betti_q)) parts.push(`Betti (Q) ${surf.betti_q.join(", ")}`);
  parts.push(`${surf.triangles.length} triangles`);
  parts.push(surf.morse_agrees ? "Morse check agrees" : "Morse check disagrees");
  const defects = Object.entries(surf.defects || {}).filter(([, n]) => n);
  if (defects.length) parts.push(defects.map(([d, n]) => `${n} ${d}`).join(", "));
  return parts.join(", ");
}

/** The caption of a two-degree-of-freedom answer. */
function surfacesCaption(answer) {
  const n = answer.surfaces.length;
  const search = answer.search || {};
  const cut = search.complete === false ? ` (search: ${search.reason})` : "";
  return `two degrees of freedom: ${n} surface${n === 1 ? "" : "s"}, ` +
    `${answer.critical_points.length} critical points${cut}; drawn in the 3D view`;
}

/** Draw the surfaces of the answer; returns the mesh vertices as projected (for picking). */
function drawSurfaces(ctx, answer, keys, project, normalise) {
  const meshes = answer.surfaces.map((surf) => keys.map((k) => surfaceCoordinate(surf, k)));
  const light = [0.3, 0.5, 0.81]; // towards the viewer, up and right
  const faces = [];
  const points = [];
  meshes.forEach((coords, s) => {
    const n = coords[0].values.length;
    const p = Array.from({ length: n }, (_, i) => {
      const q = project([0, 1, 2].map((a) => normalise(a, coords[a].values[i])));
      points.push({ x: q[0], y: q[1], depth: q[2], surface: s, index: i });
      return q;
    });
    for (const [a, b, c] of answer.surfaces[s].triangles) {
      // a triangle across the cut of an angle (-π to π) is not drawn: it would span the box
      if (coords.some((axis) => axis.angle && (
        Math.abs(axis.values[a] - axis.values[b]) > Math.PI ||
        Math.abs(axis.values[b] - axis.values[c]) > Math.PI ||
        Math.abs(axis.values[a] - axis.values[c]) > Math.PI))) continue;
      const [u, v] = [[0, 1, 2].map((i) => p[b][i] - p[a][i]),
                      [0, 1, 2].map((i) => p[c][i] - p[a][i])];
      const normal = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                      u[0] * v[1] - u[1] * v[0]];
      const len = Math.hypot(...normal) || 1;
      const facing = Math.abs(normal.reduce((sum, x, i) => sum + x * light[i], 0)) / len;
      faces.push({ a: p[a], b: p[b], c: p[c], depth: (p[a][2] + p[b][2] + p[c][2]) / 3,
                   shade: 0.35 + 0.65 * facing, colour: COLOURS[s % COLOURS.length] });
    }
  });
  faces.sort((f, g) => f.depth - g.depth); // back (smaller depth: away from the viewer) first
  ctx.lineWidth = 0.3;
  for (const f of faces) {
    ctx.globalAlpha = 0.9;
    ctx.fillStyle = shaded(f.colour, f.shade);
    ctx.strokeStyle = shaded(f.colour, 0.6 * f.shade);
    ctx.beginPath(); ctx.moveTo(f.a[0], f.a[1]); ctx.lineTo(f.b[0], f.b[1]);
    ctx.lineTo(f.c[0], f.c[1]); ctx.closePath(); ctx.fill(); ctx.stroke();
  }
  ctx.globalAlpha = 1;
  const canvas = $("view3d");
  canvas.dataset.surfaces = String(answer.surfaces.length);
  canvas.dataset.triangles = String(faces.length);
  canvas.dataset.meshVertices = String(points.length);
  return points;
}

/** A colour "#rrggbb" scaled by a shade in [0, 1]. */
function shaded(colour, shade) {
  const c = [1, 3, 5].map((i) => Math.round(parseInt(colour.slice(i, i + 2), 16) * shade));
  return `rgb(${c.join(",")})`;
}

/** The mesh vertex a click picks: the nearest one in front among those within a few pixels of
 * the pointer (the mesh hides what is behind it), else the nearest within 20 pixels. */
function pickSurfaceVertex(points, x, y) {
  const near = points.map((p) => ({ ...p, d: Math.hypot(p.x - x, p.y - y) }))
    .filter((p) => p.d <= 20);
  if (!near.length) return null;
  const close = near.filter((p) => p.d <= 6);
  if (close.length) return close.reduce((best, p) => (p.depth > best.depth ? p : best));
  return near.reduce((best, p) => (p.d < best.d ? p : best));
}

/** The positions of the linkage at a surface's mesh vertex ({vertex: position}). */
function surfacePositions(surf, index) {
  return Object.fromEntries(Object.entries(surf.positions).map(([v, walk]) => [v, walk[index]]));
}

/** Show the surfaces' topology under the 3D view. */
function showSurfaceList(answer) {
  const box = $("surface-list");
  if (!box) return;
  const surfaces = (answer && answer.surfaces) || [];
  box.replaceChildren(...surfaces.map((surf, k) => {
    const li = document.createElement("li");
    li.dataset.surface = String(k);
    li.dataset.genus = String(surf.genus ?? "");
    li.dataset.euler = String(surf.euler ?? "");
    li.dataset.triangles = String(surf.triangles.length);
    li.textContent = surfaceText(surf, k);
    return li;
  }));
}
