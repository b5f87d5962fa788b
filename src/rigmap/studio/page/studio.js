"use strict";
// What the studio's own pages share (pose.js, play.js): vectors, the camera's perspective
// (rigmap.studio.camera.screen_point's), shader programs, a mesh's normals and the
// websocket's messages (rigmap.studio.page_server.encode). Plain scripts: one global scope.

// ------------------------------------------------------------------ vectors and matrices
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const addScaled = (a, b, s) => [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const normalize = (a) => { const n = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / n, a[1] / n, a[2] / n]; };

// Rodrigues: ``v`` turned by ``angle`` about unit ``axis``
function rotate(v, axis, angle) {
  const c = Math.cos(angle), s = Math.sin(angle);
  const k = cross(axis, v), d = dot(axis, v) * (1 - c);
  return [v[0] * c + k[0] * s + axis[0] * d, v[1] * c + k[1] * s + axis[1] * d, v[2] * c + k[2] * s + axis[2] * d];
}

// the camera's frame: forward, right, up (unit vectors)
function frame(camera) {
  const forward = normalize(sub(camera.look_at, camera.position));
  const right = normalize(cross(forward, camera.up));
  return { forward, right, up: cross(right, forward) };
}

// view-projection, column-major (WebGL's order): the perspective of rigmap.studio.camera.screen_point
function viewProjection(camera, aspect) {
  const { forward, right, up } = frame(camera);
  const e = camera.position, near = 0.005, far = 100;
  const f = 1 / Math.tan(camera.fov / 2);
  const view = [
    right[0], up[0], -forward[0], 0,
    right[1], up[1], -forward[1], 0,
    right[2], up[2], -forward[2], 0,
    -dot(right, e), -dot(up, e), dot(forward, e), 1,
  ];
  const proj = [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, (2 * far * near) / (near - far), 0];
  const out = new Float32Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += proj[k * 4 + r] * view[c * 4 + k];
      out[c * 4 + r] = s;
    }
  }
  return out;
}

// the page pixel (CSS, from the canvas's top-left) of scene point ``p``
function screenPoint(camera, p, width, height) {
  const { forward, right, up } = frame(camera);
  const v = sub(p, camera.position), depth = dot(v, forward), half = Math.tan(camera.fov / 2);
  return [((dot(v, right) / (depth * half * width / height)) + 1) / 2 * width, (1 - dot(v, up) / (depth * half)) / 2 * height];
}

// where the ray through page pixel (x, y) meets the plane through ``point`` facing the camera
function onViewPlane(camera, x, y, width, height, point) {
  const { forward, right, up } = frame(camera);
  const half = Math.tan(camera.fov / 2);
  const nx = (2 * x) / width - 1, ny = 1 - (2 * y) / height;
  const ray = addScaled(addScaled(forward, right, nx * half * width / height), up, ny * half);
  const t = dot(sub(point, camera.position), forward) / dot(ray, forward);
  return addScaled(camera.position, ray, t);
}

// ------------------------------------------------------------------ programs
function program(gl, vertexSource, fragmentSource) {
  const shader = (kind, source) => {
    const s = gl.createShader(kind);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, shader(gl.VERTEX_SHADER, vertexSource));
  gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fragmentSource));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  const where = {};
  const count = (kind) => gl.getProgramParameter(p, kind);
  for (let i = 0; i < count(gl.ACTIVE_ATTRIBUTES); i++) { const a = gl.getActiveAttrib(p, i).name; where[a] = gl.getAttribLocation(p, a); }
  for (let i = 0; i < count(gl.ACTIVE_UNIFORMS); i++) { const u = gl.getActiveUniform(p, i).name; where[u] = gl.getUniformLocation(p, u); }
  return { p, where };
}

function surfaceNormals(vertices, faces) {
  const normals = new Float32Array(vertices.length);
  for (let f = 0; f < faces.length; f += 3) {
    const a = 3 * faces[f], b = 3 * faces[f + 1], c = 3 * faces[f + 2];
    const u = [vertices[b] - vertices[a], vertices[b + 1] - vertices[a + 1], vertices[b + 2] - vertices[a + 2]];
    const v = [vertices[c] - vertices[a], vertices[c + 1] - vertices[a + 1], vertices[c + 2] - vertices[a + 2]];
    const n = cross(u, v);
    for (const k of [a, b, c]) { normals[k] += n[0]; normals[k + 1] += n[1]; normals[k + 2] += n[2]; }
  }
  return normals;
}

function decode(buffer) {
  const size = new DataView(buffer).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, size)));
  const start = 4 + size + ((4 - ((4 + size) % 4)) % 4);
  return [header, new Float32Array(buffer, start, (buffer.byteLength - start) / 4)];
}

// the page's websocket at ``path``: ``onMessage(header, points)`` for each message
function connect(path, onMessage, onClose) {
  const socket = new WebSocket(`ws://${location.host}${path}`);
  socket.binaryType = "arraybuffer";
  socket.onmessage = (event) => onMessage(...decode(event.data));
  socket.onclose = onClose;
  return (command) => { if (socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(command)); };
}

// the links to the studio's other pages (``pages``: title -> route) and its viser page
function showLinks(element, pages, studio) {
  const link = (text, href) => { const a = document.createElement("a"); a.href = href; a.textContent = text; return a; };
  const items = Object.entries(pages).filter(([, route]) => route !== location.pathname).map(([title, route]) => link(title, route));
  if (studio) items.push(link("Review and Edit", studio));
  element.replaceChildren("Other pages: ", ...items.flatMap((a, k) => (k ? [" · ", a] : [a])));
}

// a mesh's surface: lit by two direct lights, both sides
const SURFACE_SHADERS = [
  `attribute vec3 position; attribute vec3 normal; uniform mat4 viewProj; varying vec3 vNormal;
   void main() { vNormal = normal; gl_Position = viewProj * vec4(position, 1.0); }`,
  `precision mediump float; varying vec3 vNormal; uniform vec3 color;
   void main() {
     vec3 n = normalize(gl_FrontFacing ? vNormal : -vNormal);
     float key = max(dot(n, normalize(vec3(0.4, 0.8, 0.6))), 0.0);
     float fill = max(dot(n, normalize(vec3(-0.6, 0.1, 0.7))), 0.0);
     gl_FragColor = vec4(color * (0.35 + 0.6 * key + 0.25 * fill), 1.0);
   }`];


function attribute(gl, where, name, buffer, size, stride = 0, offset = 0) {
  if (where[name] === undefined) return;
  gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
  gl.enableVertexAttribArray(where[name]);
  gl.vertexAttribPointer(where[name], size, gl.FLOAT, false, stride, offset);
}

// a mesh (a face rig's surface): triangles set once, vertices (metres) on every frame
class Surface {
  constructor(gl, faces, color) {
    this.gl = gl;
    this.program = program(gl, ...SURFACE_SHADERS);
    this.color = color;
    this.buffers = { vertices: gl.createBuffer(), normals: gl.createBuffer(), faces: gl.createBuffer() };
    const flat = faces.flat(), big = Math.max(...flat) > 65535;
    if (big && !gl.getExtension("OES_element_index_uint")) throw new Error("this mesh needs 32-bit indices");
    this.faces = big ? new Uint32Array(flat) : new Uint16Array(flat);
    this.indexType = big ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT;
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.faces);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, this.faces, gl.STATIC_DRAW);
  }

  setVertices(vertices) {
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.vertices);
    gl.bufferData(gl.ARRAY_BUFFER, vertices, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.normals);
    gl.bufferData(gl.ARRAY_BUFFER, surfaceNormals(vertices, this.faces), gl.DYNAMIC_DRAW);
  }

  draw(viewProj) {
    const gl = this.gl, { p, where } = this.program;
    gl.useProgram(p);
    attribute(gl, where, "position", this.buffers.vertices, 3);
    attribute(gl, where, "normal", this.buffers.normals, 3);
    gl.uniformMatrix4fv(where.viewProj, false, viewProj);
    gl.uniform3fv(where.color, this.color);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.faces);
    gl.drawElements(gl.TRIANGLES, this.faces.length, this.indexType, 0);
    gl.disableVertexAttribArray(where.normal);
  }
}

// the camera turned about its aim by a pointer's move (dx, dy pixels), never over the top
function orbit(camera, dx, dy) {
  let offset = rotate(sub(camera.position, camera.look_at), [0, 1, 0], -0.01 * dx);
  const turned = rotate(offset, normalize(cross([0, 1, 0], offset)), 0.01 * dy);
  if (Math.abs(normalize(turned)[1]) < 0.98) offset = turned;
  camera.position = addScaled(camera.look_at, offset, 1);
  camera.up = [0, 1, 0];
}

// the wheel over ``canvas`` moves ``camera()`` (once there is one) toward or away from its aim
function zoomOnWheel(canvas, camera, requestRender) {
  canvas.addEventListener("wheel", (event) => {
    const now = camera();
    if (!now) return;
    event.preventDefault();
    now.position = addScaled(now.look_at, sub(now.position, now.look_at), Math.exp(0.001 * event.deltaY));
    requestRender();
  }, { passive: false });
}

// the canvas's drawing buffer at its size on the page; returns [width, height]
function fitCanvas(gl, canvas) {
  const dpr = window.devicePixelRatio || 1;
  const width = Math.round(canvas.clientWidth * dpr), height = Math.round(canvas.clientHeight * dpr);
  if (canvas.width !== width || canvas.height !== height) { canvas.width = width; canvas.height = height; }
  gl.viewport(0, 0, width, height);
  return [width, height];
}

// one frame at the next animation frame however many times it is asked for before then
function renderOnDemand(render) {
  let pending = false;
  return () => {
    if (!pending) { pending = true; requestAnimationFrame(() => { pending = false; render(); }); }
  };
}

// the page's WebGL context: no multisampling (software WebGL's frame cost: the face's drags
// came 12 ms sooner at p95 without it, measured), and the last frame kept in the drawing
// buffer so a screenshot of the page shows it
function webgl(canvas) {
  return canvas.getContext("webgl", { antialias: false, preserveDrawingBuffer: true });
}

const FACE_COLOR = [225 / 255, 190 / 255, 170 / 255];
const BACKGROUND = [0.957, 0.957, 0.949];
