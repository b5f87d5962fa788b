"use strict";
// rigmap studio's Pose page: draws the rig the server poses and sends the effectors the user
// drags. Plain WebGL, no framework: a drag costs one websocket message each way and one frame
// (why a page of our own: rigmap/studio/page_server.py). Scene units are metres, Y up.

const HANDLE_PX = 14; // an effector's handle, CSS pixels (ours)
const PICK_PX = 18; // how near a press must be to grab a handle (ours)
const JOINT_PX = 7;
const BONE_PX = 5;
const SKELETON_COLOR = [40 / 255, 90 / 255, 200 / 255];

const canvas = document.getElementById("canvas");
const statusLine = document.getElementById("status");
const errorLine = document.getElementById("error");
const rigMenu = document.getElementById("rig");
const gl = webgl(canvas);

// bones and grid lines as screen-space quads ``width`` pixels wide (WebGL draws lines one
// pixel wide); ``viewport`` is half the canvas's size in pixels
const LINES = gl && program(
  gl,
  `attribute vec3 position; attribute vec3 other; attribute float side;
   uniform mat4 viewProj; uniform vec2 viewport; uniform float width;
   void main() {
     vec4 a = viewProj * vec4(position, 1.0); vec4 b = viewProj * vec4(other, 1.0);
     vec2 d = (b.xy / b.w - a.xy / a.w) * viewport; float len = length(d);
     vec2 along = len > 1e-6 ? d / len : vec2(1.0, 0.0);
     vec2 offset = vec2(-along.y, along.x) * side * 0.5 * width / viewport;
     gl_Position = a + vec4(offset * a.w, 0.0, 0.0);
   }`,
  `precision mediump float; uniform vec3 color; void main() { gl_FragColor = vec4(color, 1.0); }`);
const POINTS = gl && program(
  gl,
  `attribute vec3 position; uniform mat4 viewProj; uniform float size;
   void main() { gl_Position = viewProj * vec4(position, 1.0); gl_PointSize = size; }`,
  `precision mediump float; uniform vec3 color; uniform vec3 ring;
   void main() { vec2 c = gl_PointCoord * 2.0 - 1.0; float r = dot(c, c); if (r > 1.0) discard;
     gl_FragColor = vec4(r > 0.5 ? ring : color, 1.0); }`);

// ------------------------------------------------------------------ the scene
let scene = null; // the rig's layout (scene message)
let camera = null;
let points = null; // Float32Array: joints, then the surface (scene message, pose messages)
let dirty = true; // points changed since the buffers were filled
let surface = null; // a mesh rig's Surface
let dragging = null, orbiting = null;
const buffers = gl ? { bones: gl.createBuffer(), joints: gl.createBuffer(), handles: gl.createBuffer(), grid: gl.createBuffer() } : {};

function segments(pairs, at) {
  // 6 vertices per segment (two triangles), each: position, other end, side
  const out = new Float32Array(pairs.length * 6 * 7);
  let o = 0;
  const put = (a, b, side) => { out.set(a, o); out.set(b, o + 3); out[o + 6] = side; o += 7; };
  for (const [i, j] of pairs) {
    const a = at(i), b = at(j);
    put(a, b, 1); put(a, b, -1); put(b, a, -1); put(a, b, -1); put(b, a, 1); put(b, a, -1);
  }
  return out;
}

const jointAt = (i) => [points[3 * i], points[3 * i + 1], points[3 * i + 2]];

function gridLines() {
  // a floor under the character: 16 squares of an eighth of its height (ours)
  const n = scene.joints, ys = [], xs = [], zs = [];
  const shown = scene.vertices ? points.length / 3 : n;
  for (let i = 0; i < shown; i++) { xs.push(points[3 * i]); ys.push(points[3 * i + 1]); zs.push(points[3 * i + 2]); }
  const floor = Math.min(...ys), height = Math.max(...ys) - floor || 1, step = height / 8;
  const cx = (Math.min(...xs) + Math.max(...xs)) / 2, cz = (Math.min(...zs) + Math.max(...zs)) / 2;
  const ends = [];
  for (let k = -8; k <= 8; k++) {
    ends.push([[cx + k * step, floor, cz - 8 * step], [cx + k * step, floor, cz + 8 * step]]);
    ends.push([[cx - 8 * step, floor, cz + k * step], [cx + 8 * step, floor, cz + k * step]]);
  }
  return segments(ends.map((_, k) => [2 * k, 2 * k + 1]), (i) => ends[i >> 1][i & 1]);
}

function fill() {
  const jointPoints = points.subarray(0, 3 * scene.joints);
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.joints);
  gl.bufferData(gl.ARRAY_BUFFER, jointPoints, gl.DYNAMIC_DRAW);
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.bones);
  gl.bufferData(gl.ARRAY_BUFFER, segments(scene.bones, jointAt), gl.DYNAMIC_DRAW);
  if (surface) surface.setVertices(points.subarray(3 * scene.joints));
  dirty = false;
}

function drawLines(buffer, count, viewProj, color, width) {
  const { p, where } = LINES;
  gl.useProgram(p);
  attribute(gl, where, "position", buffer, 3, 28, 0);
  attribute(gl, where, "other", buffer, 3, 28, 12);
  attribute(gl, where, "side", buffer, 1, 28, 24);
  gl.uniformMatrix4fv(where.viewProj, false, viewProj);
  gl.uniform2f(where.viewport, canvas.width / 2, canvas.height / 2);
  gl.uniform1f(where.width, width * (window.devicePixelRatio || 1));
  gl.uniform3fv(where.color, color);
  gl.drawArrays(gl.TRIANGLES, 0, count);
  gl.disableVertexAttribArray(where.other);
  gl.disableVertexAttribArray(where.side);
}

function drawPoints(buffer, count, viewProj, size, color, ring) {
  const { p, where } = POINTS;
  gl.useProgram(p);
  attribute(gl, where, "position", buffer, 3);
  gl.uniformMatrix4fv(where.viewProj, false, viewProj);
  gl.uniform1f(where.size, size * (window.devicePixelRatio || 1));
  gl.uniform3fv(where.color, color);
  gl.uniform3fv(where.ring, ring);
  gl.drawArrays(gl.POINTS, 0, count);
}

function render() {
  const [width, height] = fitCanvas(gl, canvas);
  gl.clearColor(...BACKGROUND, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  if (!scene) return;
  if (dirty) fill();
  const viewProj = viewProjection(camera, width / height);
  gl.enable(gl.DEPTH_TEST);
  drawLines(buffers.grid, scene.gridCount, viewProj, [0.82, 0.82, 0.8], 1);
  if (surface) surface.draw(viewProj);
  drawLines(buffers.bones, scene.bones.length * 6, viewProj, SKELETON_COLOR, BONE_PX);
  drawPoints(buffers.joints, scene.joints, viewProj, JOINT_PX, SKELETON_COLOR, SKELETON_COLOR);
  gl.disable(gl.DEPTH_TEST); // handles stay grabbable over a mesh rig's surface
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.handles);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(scene.targets.flat()), gl.DYNAMIC_DRAW);
  drawPoints(buffers.handles, scene.targets.length, viewProj, HANDLE_PX, [1.0, 0.6, 0.1], [0.45, 0.2, 0.0]);
}

const requestRender = renderOnDemand(render);

function showScene(header, data) {
  scene = header;
  camera = header.camera;
  points = data;
  surface = scene.vertices ? new Surface(gl, scene.faces, FACE_COLOR) : null;
  const grid = gridLines();
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.grid);
  gl.bufferData(gl.ARRAY_BUFFER, grid, gl.STATIC_DRAW);
  scene.gridCount = grid.length / 7;
  dirty = true;
  rigMenu.value = scene.rig;
  requestRender();
}

// ------------------------------------------------------------------ the server
function showListing(rows) {
  const table = document.getElementById("listing");
  table.replaceChildren(...rows.map(([name, value]) => {
    const row = document.createElement("tr");
    for (const text of [name, value.toFixed(3)]) {
      const cell = document.createElement("td");
      cell.textContent = text;
      row.appendChild(cell);
    }
    return row;
  }));
  document.getElementById("listing-head").textContent = rows.length ? `The ${rows.length} controls most moved from rest:` : "";
}

function onMessage(header, data) {
  if (header.type === "pose") {
    if (!scene) return;
    points = data;
    dirty = true;
    requestRender(); // before the status line changes: the frame that shows it draws the pose
    errorLine.textContent = "";
    statusLine.textContent = header.status;
  } else if (header.type === "scene") {
    showScene(header, data);
    statusLine.textContent = header.status;
  } else if (header.type === "rigs") {
    rigMenu.replaceChildren(...header.names.map((name) => new Option(name, name)));
    if (header.current) rigMenu.value = header.current;
    statusLine.textContent = header.status;
  } else if (header.type === "links") {
    showLinks(document.getElementById("links"), header.pages, header.studio);
  } else if (header.type === "status") {
    statusLine.textContent = header.status;
  } else if (header.type === "listing") {
    showListing(header.rows);
  } else if (header.type === "exported") {
    document.getElementById("exported").textContent = `Exported ${header.name}`;
  } else if (header.type === "error") {
    errorLine.textContent = header.message;
    document.getElementById("exported").textContent = "";
  }
}
const send = connect("/pose/ws", onMessage, () => {
  statusLine.textContent = "The studio stopped (reload when it runs again).";
});

// ------------------------------------------------------------------ input
function handleUnder(x, y) {
  let best = -1, nearest = PICK_PX;
  scene.targets.forEach((target, k) => {
    const [px, py] = screenPoint(camera, target, canvas.clientWidth, canvas.clientHeight);
    const d = Math.hypot(px - x, py - y);
    if (d < nearest) { nearest = d; best = k; }
  });
  return best;
}

canvas.addEventListener("pointerdown", (event) => {
  if (!scene) return;
  canvas.setPointerCapture(event.pointerId);
  const k = handleUnder(event.offsetX, event.offsetY);
  if (k >= 0) {
    // the handle keeps its offset from the pointer: a press off its centre does not jump it
    const start = scene.targets[k].slice();
    const grab = onViewPlane(camera, event.offsetX, event.offsetY, canvas.clientWidth, canvas.clientHeight, start);
    dragging = { k, start, grab };
    send({ type: "drag", phase: "start", effector: scene.effectors[k], target: scene.targets[k] });
  } else {
    orbiting = { x: event.offsetX, y: event.offsetY };
  }
});

// raw pointer updates where the browser has them: they come as the input does, not at the
// next frame as pointermove does (a frame sooner to the server)
const MOVE_EVENT = "onpointerrawupdate" in window ? "pointerrawupdate" : "pointermove";
canvas.addEventListener(MOVE_EVENT, (event) => {
  if (dragging) {
    const k = dragging.k;
    const hit = onViewPlane(camera, event.offsetX, event.offsetY, canvas.clientWidth, canvas.clientHeight, dragging.start);
    scene.targets[k] = addScaled(dragging.start, sub(hit, dragging.grab), 1);
    send({ type: "drag", phase: "move", effector: scene.effectors[k], target: scene.targets[k] });
    requestRender();
  } else if (orbiting) {
    orbit(camera, event.offsetX - orbiting.x, event.offsetY - orbiting.y);
    orbiting = { x: event.offsetX, y: event.offsetY };
    requestRender();
  }
});

function release(event) {
  if (dragging) {
    const k = dragging.k;
    send({ type: "drag", phase: "end", effector: scene.effectors[k], target: scene.targets[k] });
  }
  dragging = null;
  orbiting = null;
  if (canvas.hasPointerCapture(event.pointerId)) canvas.releasePointerCapture(event.pointerId);
}
canvas.addEventListener("pointerup", release);
canvas.addEventListener("pointercancel", release);

zoomOnWheel(canvas, () => camera, requestRender);

rigMenu.addEventListener("change", () => send({ type: "rig", name: rigMenu.value }));
document.getElementById("reset").addEventListener("click", () => scene && send({ type: "rig", name: scene.rig }));
document.getElementById("export").addEventListener("click", () => send({ type: "export", as: "json" }));
document.getElementById("export-blend").addEventListener("click", () => {
  document.getElementById("exported").textContent = "Writing the .blend (Blender)…";
  send({ type: "export", as: "blend" });
});
window.addEventListener("resize", requestRender);
if (!gl) statusLine.textContent = "This page needs WebGL, which this browser does not offer.";
