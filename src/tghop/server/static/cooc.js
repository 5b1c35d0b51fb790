// tghop serve's page, Co-occurrence mode (docs/serve.md, /api/cooc): a checkpoint of
// `tghop cooc train`, crops of its exemplar placed by clicking, a morph from crop 1 to crop 2
// and an edit painted with the brush of Paint mode (board.js's board). Loaded last (app.js lists
// the files), it uses the others' helpers ($, errorOf, withBusy, showResult, postImage, withWarning,
// offerDownload, the boards, swatch and colourOf, brushPoint).
"use strict";

// The checkpoint (id, its summary), the exemplar's picture (an Image, or null) and the crops:
// one [y, x] (or null) per slot; `active` is the slot the next click places and the brush paints.
const cooc = { id: null, info: null, picture: null, crops: [], active: 0, stem: "cooc" };
const COOC_SLOTS = 4;
const coocBoard = makeBoard("cooc-guide", "cooc-cursor", "cooc-brush", () => cooc.active);

function sayCooc(text, isError) {
  sayIn($("cooc-message"), text, isError);
}

function updateCoocButtons() {
  const ready = !state.busy && Boolean(cooc.id);
  $("cooc-morph-go").disabled = !ready || !cooc.crops[0] || !cooc.crops[1];
  $("cooc-edit-go").disabled = !ready || !cooc.crops.some(Boolean);
}

function coocShown() {
  if (state.coocMissing) {
    sayCooc("this server has no PyTorch, which co-occurrence models need: install it there " +
            "(pip install 'tghop[metrics]') and start tghop serve again", true);
  } else if (!cooc.id) sayCooc("load a co-occurrence checkpoint (a .pt file of tghop cooc train)");
  else {
    resizeCoocBoard();
    showCoocBoard(true);
  }
}

// The edit's canvas sized and brought into view with the tools above it (0.60; 0.59 left it below the fold, as
// Paint's and Inpaint's pictures were before 0.59), when the work opens (a checkpoint loaded, the mode chosen with
// one) and when a canvas of a new size is made: from the mode's message (where a crop went), the crops (the colours
// to place and paint with) and the exemplar down, where the window has room for the canvas at its size under them
// (at 1024x700 a 64x64 exemplar's, a 128x192 canvas); else from the edit's heading. Enlarged up to 4 times, 640 px,
// only as far as the window shows it whole (never below its size). `opening` (a checkpoint loaded, the mode chosen):
// where the window has no room for the crops and the canvas at once (400x800) and no crop is placed yet, the message,
// the crops and the exemplar are brought into view instead, the first step (0.62; 0.61 showed the edit, the message
// "click on the exemplar to place crop 1" and the exemplar above it, out of sight).
function showCoocBoard(opening) {
  const fits = sizeCoocBoard();
  if (fits === null) return;
  if (opening && !fits && !cooc.crops.some(Boolean)) intoView($("cooc-exemplar"), $("cooc-message"));
  else intoView($("cooc-guide-box"), fits ? $("cooc-message") : $("cooc-edit-title"));
}

// The edit's canvas sized as showCoocBoard says (a window resized too: app.js): whether it fits under the message, the
// crops and the exemplar (null: not shown).
function sizeCoocBoard() {
  const canvas = $("cooc-guide"), box = $("cooc-guide-box"), w = canvas.width, h = canvas.height;
  if ($("cooc").hidden || $("cooc-work").hidden || !w || !h) return null;
  const fits = roomFor(box, w, h, $("cooc-message")) >= w, from = fits ? $("cooc-message") : $("cooc-edit-title");
  canvas.style.width = `${Math.max(w, Math.min(4 * w, 640, roomFor(box, w, h, from)))}px`;
  return fits;
}

// A checkpoint loaded; what went wrong said in the mode's message (0.63: a server that did not answer left "uploading
// NAME" said for good, the browser's error on its console alone).
async function uploadCooc(file) {
  try {
    await loadCooc(file);
  } catch (e) {
    sayCooc(e.message, true);
  }
}

async function loadCooc(file) {
  if (!file) return;
  const radio = $("mode-cooc");
  if (!radio.checked) { radio.checked = true; setMode("cooc"); }
  sayCooc(`uploading ${file.name}`);
  const response = await answeredFetch("/api/cooc", {
    method: "POST", body: file, headers: { "Content-Type": "application/octet-stream" },
  });
  if (!response.ok) { sayCooc(await errorOf(response), true); return; }
  const { id, notes } = await response.json();  // notes: what reading the file warned of, as a model upload's
  const info = await answeredFetch(`/api/cooc/${id}`);
  if (!info.ok) { sayCooc(await errorOf(info), true); return; }
  cooc.id = id;
  cooc.info = await info.json();
  cooc.crops = new Array(COOC_SLOTS).fill(null);
  cooc.active = 0;
  cooc.picture = null;
  const [h, w] = cooc.info.exemplar_shape;
  $("cooc-summary").textContent = withWarning(`${file.name}: exemplar ${h}x${w}, ${cooc.info.crop_size} px crops, ` +
    `${cooc.info.step} of ${cooc.info.n_steps} steps trained`, (notes || []).join("; "));
  cooc.stem = modelStem(file.name);  // its name as the server's Content-Disposition gives it (download_name)
  offerDownload($("cooc-download"), `/api/cooc/${id}/file?name=${encodeURIComponent(cooc.stem)}`,
                `tghop-cooc-${cooc.stem}-${id.slice(0, 12)}.pt`);
  for (const which of ["a", "b"]) $(`cooc-boost-${which}`).max = String(cooc.info.n_clusters - 1);
  $("cooc-work").hidden = false;
  $("cooc-picture-button").hidden = Boolean(cooc.info.builtin);
  renderCoocCrops();
  resizeCoocBoard(true);
  drawCoocExemplar();  // its size shown, so that the edit's canvas is sized and placed under it (showCoocBoard)
  showCoocBoard(true);
  if (cooc.info.builtin) {
    showCoocPicture(`/api/builtins/${cooc.info.builtin}.png`, `builtin:${cooc.info.builtin}`);
  } else {
    sayCooc("click on the exemplar to place crop 1 (pick the exemplar's image to see it)");
  }
  updateButtons();
}

// The exemplar the checkpoint was trained on, to see where the crops are (it must be of its size).
function showCoocPicture(url, name) {
  const img = new Image();
  img.onload = () => {
    const [h, w] = cooc.info.exemplar_shape;
    if (img.naturalHeight !== h || img.naturalWidth !== w) {
      sayCooc(`${name} is ${img.naturalHeight}x${img.naturalWidth} but the checkpoint's exemplar is ${h}x${w}; ` +
        "pick the image it was trained on", true);
      return;
    }
    cooc.picture = img;
    drawCoocExemplar();
    sayCooc("click on the exemplar to place the chosen crop");
  };
  img.onerror = () => sayCooc(`the browser cannot show ${name}`, true);
  img.src = url;
}

function renderCoocCrops() {
  const group = $("cooc-crops");
  group.textContent = "";
  cooc.crops.forEach((crop, i) => {
    const label = document.createElement("label");
    const radio = document.createElement("input");
    radio.type = "radio";
    radio.name = "cooc-crop";
    radio.id = `cooc-crop-${i}`;
    radio.checked = i === cooc.active;
    radio.addEventListener("change", () => { if (radio.checked) cooc.active = i; });
    // where it is in a span of its own, which a narrow window hides from sight (style.css): the crops on one line
    const at = document.createElement("span");
    at.className = "crop-at";
    at.textContent = crop ? ` (${crop[0]}, ${crop[1]})` : "";
    label.append(radio, swatch(i), `crop ${i + 1}`, at);
    group.append(label);
  });
  updateCoocButtons();
}

// The exemplar (or a checkerboard of its size) with every placed crop outlined in its colour.
function drawCoocExemplar() {
  const [h, w] = cooc.info.exemplar_shape;
  const canvas = $("cooc-exemplar");
  canvas.width = w;
  canvas.height = h;
  canvas.style.width = `${Math.max(w, Math.min(2 * w, 512))}px`;
  const ctx = canvas.getContext("2d");
  if (cooc.picture) {
    ctx.drawImage(cooc.picture, 0, 0);
  } else {
    const cell = cooc.info.s;
    for (let y = 0; y < h; y += cell) {
      for (let x = 0; x < w; x += cell) {
        ctx.fillStyle = ((x + y) / cell) % 2 ? "#d8d8d8" : "#ececec";
        ctx.fillRect(x, y, cell, cell);
      }
    }
  }
  const size = cooc.info.crop_size;
  ctx.lineWidth = Math.max(2, Math.round(w / 256));
  cooc.crops.forEach((crop, i) => {
    if (!crop) return;
    ctx.strokeStyle = colourOf(i);
    ctx.strokeRect(crop[1] + 1, crop[0] + 1, size - 2, size - 2);
  });
  numberCoocCrops();
  canvas.dataset.ready = "1";
}

// Each placed crop's number in its top left corner, in the page's text over the canvas (0.63: 0.62 drew it on the
// canvas at the exemplar's own resolution, blurred where the canvas is shown larger, a crop's number half under the
// outline of a crop over it); numbers of crops at one corner side by side.
function numberCoocCrops() {
  const box = $("cooc-exemplar-box"), [h, w] = cooc.info.exemplar_shape, corners = [];
  for (const old of box.querySelectorAll(".crop-number")) old.remove();
  cooc.crops.forEach((crop, i) => {
    if (!crop) return;
    const number = document.createElement("span");
    number.className = "crop-number";
    number.textContent = String(i + 1);
    number.style.borderColor = colourOf(i);
    number.style.left = `calc(${100 * crop[1] / w}% + ${corners.filter((c) => c === `${crop}`).length * 1.8}em)`;
    number.style.top = `${100 * crop[0] / h}%`;
    number.setAttribute("aria-hidden", "true");  // the crops' buttons above say where each is
    corners.push(`${crop}`);
    box.append(number);
  });
}

// A click places the active crop centred on it, on the grid of s pixels, inside the exemplar;
// the next empty slot becomes the active one.
function onCoocClick(event) {
  if (!cooc.info) return;
  const [px, py] = brushPoint(event, $("cooc-exemplar"));
  const { s, crop_size: size, exemplar_shape: [h, w] } = cooc.info;
  const place = (v, n) => Math.max(0, Math.min(Math.floor((v - size / 2) / s), Math.floor(n / s) - size / s)) * s;
  const placed = cooc.active, [y, x] = cooc.crops[placed] = [place(py, h), place(px, w)];
  const next = cooc.active + 1;
  if (next < COOC_SLOTS && !cooc.crops[next]) cooc.active = next;
  renderCoocCrops();
  drawCoocExemplar();
  // Where it went, and what a click or the brush now does (the message said "place crop 1" still).
  sayCooc(`crop ${placed + 1} is at (${y}, ${x}), outlined on the exemplar; ` + (cooc.active === placed
    ? `a click moves it, and the brush paints with it below`
    : `the next click places crop ${cooc.active + 1}, and the brush paints with it below`));
}

// A new edit board at the edit's size, all crop 1.
function resizeCoocBoard(force) {
  const h = Number($("cooc-height").value), w = Number($("cooc-width").value);
  if (!(h > 0 && w > 0 && h * w <= 2048 * 2048)) { sayCooc("set the edit's height and width first", true); return; }
  if (!force && coocBoard.labels && coocBoard.h === h && coocBoard.w === w) return;
  resetBoard(coocBoard, h, w, 0);
}

function onCoocMorph() {
  if (!cooc.id || !cooc.crops[0] || !cooc.crops[1]) return;
  withBusy($("cooc-morph-go"), async () => {
    const body = { a: cooc.crops[0], b: cooc.crops[1], length: Number($("cooc-length").value),
      seed: Number($("cooc-morph-seed").value) };
    sayCooc("morphing");
    const [blob, seed] = await withProgress("cooc-progress",
                                            (headers) => postImage(`/api/cooc/${cooc.id}/morph`, body, headers));
    showResult(URL.createObjectURL(blob), seed, blob, "cooc-morph", undefined,
               { models: [cooc.stem], size: [cooc.info.crop_size, body.length * cooc.info.s], tile: false });
    await coocDone(blob, `done (seed ${seed}): the strip is below`);
  }, sayCooc);
}

// A morph's or an edit's result shown as a thumbnail beside the edit's canvas, as Paint's is (0.62: 0.61 said "the
// strip is below" or "the result is below" alone, the result under the canvas out of sight at 1024x700 and far below
// the fold at 400x800), said where it is, and scrolled into view where it is out of sight (under the canvas in a narrow
// window).
async function coocDone(blob, said, warning) {
  showThumb("cooc-result", blob);
  sayCooc(withWarning(`${said}, ${thumbSaid("cooc-result", $("cooc-guide-box"), "the edit's canvas")}`, warning));
  await thumbInView("cooc-result");
}

// The edit's boost [a, b, factor], or null for a factor of 1 (the server checks the values).
function coocBoost() {
  const [a, b, f] = ["a", "b", "factor"].map((k) => $(`cooc-boost-${k}`).value.trim());
  if (f === "" || a === "" || b === "") throw new Error("set the boost's clusters and factor (factor 1: no boost)");
  return Number(f) === 1 ? null : [Number(a), Number(b), Number(f)];
}

// The painted crops, in slot order; labels (grey levels, darkest for the first) only for two or more.
function onCoocEdit() {
  if (!cooc.id) return;
  withBusy($("cooc-edit-go"), async () => {
    resizeCoocBoard();
    const used = [...new Set(coocBoard.labels)].sort((a, b) => a - b);
    const unplaced = used.find((i) => !cooc.crops[i]);
    if (unplaced !== undefined) {
      throw new Error(`crop ${unplaced + 1} is painted but not placed: click on the exemplar to place it`);
    }
    const body = { crops: used.map((i) => cooc.crops[i]), size: [coocBoard.h, coocBoard.w],
      seed: Number($("cooc-edit-seed").value) };
    const boost = coocBoost();
    if (boost) body.boost = boost;
    if (used.length > 1) {
      body.labels = boardPng(coocBoard, new Map(used.map((k, j) => [k, Math.round(255 * j / (used.length - 1))])));
    }
    sayCooc("generating");
    const [blob, seed, , warning] = await withProgress(
      "cooc-progress", (headers) => postImage(`/api/cooc/${cooc.id}/edit`, body, headers));
    showResult(URL.createObjectURL(blob), seed, blob, "cooc-edit", undefined,
               { models: [cooc.stem], size: body.size, tile: false });
    await coocDone(blob, `done (seed ${seed}): the result is below`, warning);
  }, sayCooc);
}

function initCooc() {
  // Each chooser emptied once read, as the page's others (app.js): the same file chosen again is a change (0.62; 0.61
  // did nothing when the checkpoint or its picture was chosen again, after a refusal or to start its crops over)
  $("cooc-file").addEventListener("change", (e) => { uploadCooc(e.target.files[0]); e.target.value = ""; });
  $("cooc-picture").addEventListener("change", (e) => {
    const file = e.target.files[0];
    if (file && cooc.info) showCoocPicture(URL.createObjectURL(file), file.name);
    e.target.value = "";
  });
  $("cooc-exemplar").addEventListener("click", onCoocClick);
  wireBoard(coocBoard);
  $("cooc-brush").addEventListener("input", () => {
    $("cooc-brush-size").textContent = `${$("cooc-brush").value} px`;
  });
  $("cooc-reset").addEventListener("click", () => { resizeCoocBoard(true); sayCooc(""); });
  for (const id of ["cooc-height", "cooc-width"]) {
    $(id).addEventListener("change", () => {
      const [h, w] = [coocBoard.h, coocBoard.w];
      resizeCoocBoard();
      if (coocBoard.h !== h || coocBoard.w !== w) showCoocBoard();  // a new canvas: sized and in view
    });
  }
  $("cooc-morph-go").addEventListener("click", onCoocMorph);
  $("cooc-edit-go").addEventListener("click", onCoocEdit);
}

document.addEventListener("DOMContentLoaded", initCooc);
