"use strict";
// rigmap studio's Play page: draws each frame of the latent face the server streams at its
// deadline (24 frames/s) on the next animation frame, and sends the user's commands and
// moves in the game (why a page of our own: rigmap/studio/page_server.py).

const canvas = document.getElementById("canvas");
const statusLine = document.getElementById("status");
const modelMenu = document.getElementById("model");
const takeMenu = document.getElementById("take");
const gl = webgl(canvas);

let camera = null;
let surface = null;
let vertices = null; // the newest frame's (metres)
let fresh = false; // a frame came since the last draw
let orbiting = null;

function render() {
  const [width, height] = fitCanvas(gl, canvas);
  gl.clearColor(...BACKGROUND, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  if (!surface) return;
  if (fresh) { surface.setVertices(vertices); fresh = false; }
  gl.enable(gl.DEPTH_TEST);
  surface.draw(viewProjection(camera, width / height));
}
const requestRender = renderOnDemand(render);

function setOptions(menu, names) {
  const now = [...menu.options].map((o) => o.value);
  if (now.length === names.length && now.every((n, k) => n === names[k])) return;
  const kept = menu.value;
  menu.replaceChildren(...names.map((name) => new Option(name, name)));
  if (names.includes(kept)) menu.value = kept;
}

function showBoard(cells, over) {
  const board = document.getElementById("board");
  if (board.children.length !== 9) {
    board.replaceChildren(...cells.map((_, k) => {
      const button = document.createElement("button");
      button.addEventListener("click", () => send({ type: "cell", cell: k }));
      return button;
    }));
  }
  cells.forEach((label, k) => {
    const button = board.children[k];
    if (button.textContent !== label) button.textContent = label;
    button.disabled = over || !/^[1-9]$/.test(label);
  });
}

function onMessage(header, data) {
  if (header.type === "frame") {
    vertices = data;
    fresh = true;
    requestRender();
  } else if (header.type === "state") {
    statusLine.textContent = header.status;
    document.getElementById("game").textContent = header.game;
    showBoard(header.cells, header.over);
    setOptions(takeMenu, header.takes);
  } else if (header.type === "scene") {
    camera = header.camera;
    surface = new Surface(gl, header.faces, FACE_COLOR);
    vertices = data;
    fresh = true;
    setOptions(modelMenu, header.models);
    document.getElementById("idle-frames").value = header.idle_frames;
    requestRender();
  } else if (header.type === "links") {
    showLinks(document.getElementById("links"), header.pages, header.studio);
  } else if (header.type === "error") {
    statusLine.textContent = header.message;
  }
}
const send = connect("/play/ws", onMessage, () => {
  statusLine.textContent = "The studio stopped (reload when it runs again).";
});

const integer = (id) => Number.parseInt(document.getElementById(id).value, 10);
document.getElementById("transition").addEventListener("click", () => send({ type: "transition", model: modelMenu.value }));
document.getElementById("play").addEventListener("click", () => send({ type: "play", take: takeMenu.value }));
document.getElementById("move").addEventListener("click", () => send({ type: "move", take: takeMenu.value, frame: integer("frame") }));
document.getElementById("idle").addEventListener("click", () => send({ type: "idle", frames: integer("idle-frames") }));
document.getElementById("new-game").addEventListener("click", () => send({ type: "new_game" }));

canvas.addEventListener("pointerdown", (event) => {
  canvas.setPointerCapture(event.pointerId);
  orbiting = { x: event.offsetX, y: event.offsetY };
});
canvas.addEventListener("pointermove", (event) => {
  if (!orbiting || !camera) return;
  orbit(camera, event.offsetX - orbiting.x, event.offsetY - orbiting.y);
  orbiting = { x: event.offsetX, y: event.offsetY };
  requestRender();
});
canvas.addEventListener("pointerup", () => { orbiting = null; });
zoomOnWheel(canvas, () => camera, requestRender);
window.addEventListener("resize", requestRender);
if (!gl) statusLine.textContent = "This page needs WebGL, which this browser does not offer.";
