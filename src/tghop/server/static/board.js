// tghop serve's page: the palette and the boards painted by hand, Paint mode's guide (paint.js)
// and the co-occurrence edit's (cooc.js). Loaded before both: they make their board when loaded.
"use strict";

// Every model fitted or loaded on this page (state.models) has a brush colour of its own.
const PALETTE = ["#e6194b", "#3cb44b", "#4363d8", "#ffe119", "#911eb4", "#f58231", "#42d4f4", "#f032e6"];

function colourOf(index) { return PALETTE[index % PALETTE.length]; }

function swatch(index) {
  const el = document.createElement("span");
  el.className = "swatch";
  el.style.background = colourOf(index);
  return el;
}

// A board: a canvas with one label per pixel, drawn in the palette's colours and painted by
// hand (not with the canvas's antialiased strokes), so every pixel is exactly one label's.
// Paint mode's guide (labels: indices into state.models) is one; the co-occurrence edit's is another.
function makeBoard(canvasId, cursorId, brushId, labelOf) {
  return { canvas: canvasId, cursor: cursorId, brush: brushId, labelOf, labels: null, h: 0, w: 0, last: null,
    painting: false, history: [] };
}

// Undo (Paint's): the labels before each stroke, Reset or guide file, the latest last (UNDO_STEPS: inpaint.js);
// `what`: the step's name, said when it is undone ("a stroke", "Reset", "the guide file wall.png").
function rememberBoard(b, what = "a stroke", labels = b.labels) {
  if (!labels) return;
  b.history.push({ labels: labels.slice(), what });
  if (b.history.length > UNDO_STEPS) b.history.shift();
  updateButtons();
}

// The step undone: its name (null: nothing undone).
function undoBoard(b) {
  const step = b.history.pop();
  let what = null;
  if (step && step.labels.length === b.h * b.w) {
    b.labels = step.labels;
    drawBoard(b, 0, 0, b.w, b.h);
    what = step.what;
  }
  updateButtons();
  return what;
}

// A new blank board of h x w pixels, all label `fill`, shown larger when small (up to 4 times, at most 640 px wide).
function resetBoard(b, h, w, fill) {
  b.h = h;
  b.w = w;
  b.labels = new Uint8Array(h * w).fill(fill);
  b.history = [];  // a new board (Reset keeps the one before it: paint.js)
  updateButtons();  // Paint's Undo off (0.62: setMode said Paint's hint after the reset, which turned it off then)
  const canvas = $(b.canvas);
  canvas.width = w;
  canvas.height = h;
  canvas.style.width = `${Math.max(w, Math.min(4 * w, 640))}px`;
  drawBoard(b, 0, 0, w, h);
  canvas.dataset.ready = "1";
}

function drawBoard(b, x0, y0, x1, y1) {
  const w = x1 - x0, h = y1 - y0;
  if (w <= 0 || h <= 0) return;
  const rgb = PALETTE.map((c) => [1, 3, 5].map((k) => parseInt(c.slice(k, k + 2), 16)));
  const ctx = context2d($(b.canvas));
  const image = ctx.createImageData(w, h);
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) {
      const c = rgb[b.labels[(y + y0) * b.w + x + x0] % rgb.length], o = 4 * (y * w + x);
      image.data[o] = c[0]; image.data[o + 1] = c[1]; image.data[o + 2] = c[2]; image.data[o + 3] = 255;
    }
  }
  ctx.putImageData(image, x0, y0);
}

// Discs of the brush's diameter along the segment, in whole pixels.
function paintBoard(b, from, to) {
  const label = b.labelOf();
  if (label === null || !b.labels) return;
  const r = Number($(b.brush).value) / 2;
  const steps = Math.max(1, Math.ceil(Math.hypot(to[0] - from[0], to[1] - from[1]) / Math.max(1, r / 2)));
  const x0 = Math.max(0, Math.floor(Math.min(from[0], to[0]) - r));
  const x1 = Math.min(b.w, Math.ceil(Math.max(from[0], to[0]) + r));
  const y0 = Math.max(0, Math.floor(Math.min(from[1], to[1]) - r));
  const y1 = Math.min(b.h, Math.ceil(Math.max(from[1], to[1]) + r));
  for (let s = 0; s <= steps; s++) {
    const cx = from[0] + (to[0] - from[0]) * s / steps, cy = from[1] + (to[1] - from[1]) * s / steps;
    for (let y = Math.max(y0, Math.floor(cy - r)); y < Math.min(y1, Math.ceil(cy + r)); y++) {
      for (let x = Math.max(x0, Math.floor(cx - r)); x < Math.min(x1, Math.ceil(cx + r)); x++) {
        if ((x + 0.5 - cx) ** 2 + (y + 0.5 - cy) ** 2 <= r * r) b.labels[y * b.w + x] = label;
      }
    }
  }
  drawBoard(b, x0, y0, x1, y1);
}

// The pointer paints on the board; a circle of the brush's size follows it.
function wireBoard(b) {
  const canvas = $(b.canvas);
  const up = () => { b.painting = false; b.last = null; };
  canvas.addEventListener("pointerdown", (event) => {
    if (event.button !== 0 || !b.labels) return;
    event.preventDefault();
    rememberBoard(b);
    canvas.setPointerCapture(event.pointerId);
    b.painting = true;
    b.last = brushPoint(event, canvas);
    paintBoard(b, b.last, b.last);
  });
  canvas.addEventListener("pointermove", (event) => {
    moveCursor(event, canvas, $(b.cursor), $(b.brush));
    if (!b.painting) return;
    const point = brushPoint(event, canvas);
    paintBoard(b, b.last, point);
    b.last = point;
  });
  canvas.addEventListener("pointerup", up);
  canvas.addEventListener("pointercancel", up);
  canvas.addEventListener("pointerleave", () => { $(b.cursor).hidden = true; });
}

// The board as a PNG data: URL of grey levels, `levels` a Map from label to level (0-255).
function boardPng(b, levels) {
  const out = document.createElement("canvas");
  out.width = b.w;
  out.height = b.h;
  const ctx = out.getContext("2d");
  const image = ctx.createImageData(b.w, b.h);
  for (let i = 0; i < b.labels.length; i++) {
    const v = levels.get(b.labels[i]);
    image.data[4 * i] = image.data[4 * i + 1] = image.data[4 * i + 2] = v;
    image.data[4 * i + 3] = 255;
  }
  ctx.putImageData(image, 0, 0);
  return out.toDataURL("image/png");
}
