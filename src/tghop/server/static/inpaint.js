// tghop serve's page, Inpaint mode: a picture (the latest result or the user's), a mask painted on
// it with the brush, Fill (the masked pixels) and Extend (a larger picture around it).
"use strict";

function sayInpaint(text, isError, onlyNew) {
  sayIn($("inpaint-message"), text, isError, onlyNew);
}

// What Fill and Extend need that they lack (their buttons are off meanwhile; updateButtons), or "".
function inpaintHint() {
  if (state.material && !editor.maps) {
    sayInpaint("this model is a material: Fill and Extend fill every map of one of its results; generate first",
               true, true);
  } else if (!editor.blob) sayInpaint("generate an image first, or use a picture of your own", false, true);
  else sayInpaint("", false, true);
}

// The picture to paint on: the latest result, or a picture the user chose (a new picture: nothing to undo).
// `maps`: a material result's maps (the albedo first), sent with the picture to Fill and Extend.
function setEditorPicture(blob, name, maps) {
  editor.history = [];
  editor.maps = maps || null;
  if (editor.url) URL.revokeObjectURL(editor.url);
  editor.blob = blob;
  editor.name = name || "picture.png";
  editor.url = URL.createObjectURL(blob);
  const img = $("editor-base");
  img.onload = () => {
    const canvas = $("mask");
    const w = img.naturalWidth, h = img.naturalHeight;
    canvas.width = w;  // a new size clears the mask
    canvas.height = h;
    $("extend-height").placeholder = String(h);  // Extend's fields start from the picture's size
    $("extend-width").placeholder = String(w);
    followPicture(h, w);
    clearMask();
    if (editor.pendingMask && editor.pendingMask.width === w && editor.pendingMask.height === h) {
      context2d(canvas).putImageData(editor.pendingMask, 0, 0);  // an undone Fill's hole
    }
    editor.pendingMask = null;
    $("editor").hidden = false;
    sizeEditor();
    $("editor").dataset.ready = "1";
  };
  img.onerror = () => {
    editor.blob = null;  // not sent to Fill or Extend
    $("editor").hidden = true;
    updateButtons();
    sayInpaint(`the browser cannot show ${editor.name}; use a PNG or JPEG picture`, true);
  };
  $("editor").dataset.ready = "";
  img.src = editor.url;
  updateButtons();
  inpaintHint();
}

// Extend's "grow to" fields follow the picture to paint on (0.63): a size set for one picture (by Extend, by its Undo,
// or typed) moves with the next picture of another size (another result, one of Recent results, one an Undo brought
// back), grown by the same step. 0.62 kept the size, and Extend refused it as no larger than the new picture.
function followPicture(h, w) {
  const from = editor.growFrom;
  editor.growFrom = [h, w];
  if (!from || (from[0] === h && from[1] === w)) return;
  let moved = false;
  for (const [field, was, now] of [[$("extend-height"), from[0], h], [$("extend-width"), from[1], w]]) {
    const value = Number(field.value.trim() || NaN);  // empty: the picture's own size (its placeholder)
    if (Number.isFinite(value)) { field.value = String(Math.max(now, value - was + now)); moved = true; }
  }
  if (moved) keepFields();  // across a reload too (history.js)
}

// A size typed in Extend's fields is one for the picture shown now (followPicture).
function growTyped() {
  const img = $("editor-base");
  editor.growFrom = editor.blob && img.naturalWidth ? [img.naturalHeight, img.naturalWidth] : null;
}

// Small pictures are shown larger (up to 3 times, at most 640 pixels wide) to paint on; while Inpaint is shown, no
// larger than lets the mode's row, its tools and the whole picture be seen at once (roomFor; a picture shown at its
// size stays so), and the strip of fills under it where there is one (0.61: at 1024x700 a 128x192 result filled the
// window, the fills to pick from below the fold). 0.58 showed a 256x256 result 640 px high under the tools: at
// 1024x700 it ran below the fold. At zoom 1:1, at its size.
function sizeEditor() {
  const box = $("editor"), img = $("editor-base"), w = img.naturalWidth, h = img.naturalHeight;
  if (!w || !h) return;
  const room = $("inpaint").hidden ? Infinity : roomFor(box, w, h, editorTop(), stripBelow());
  // at zoom 1:1 at its size, its pixels the screen's (0.63: 0.62's zoom left it as large as it was)
  const zoom = document.body.classList.contains("zoom");
  box.style.width = `${zoom ? w : Math.max(w, Math.min(3 * w, 640, room))}px`;
}

// The height of the strip of fills under the picture and the gap above it (0: none).
function stripBelow() {
  const strip = $("strip");
  if (!strip.childElementCount) return 0;
  return Math.max(0, strip.getBoundingClientRect().bottom - $("editor").getBoundingClientRect().bottom);
}

// What is seen above the picture to paint on: from the mode's row, or (0.61) from the brush's tools where the window
// has no room for the picture at its size under the row and the mode's help (a narrow window: 400x800 left the
// picture below the fold, the help, the tools and the Extend row above it).
function editorTop() {
  const box = $("editor"), img = $("editor-base"), w = img.naturalWidth, h = img.naturalHeight;
  if (!w || !h || roomFor(box, w, h, $("modes-row"), stripBelow()) >= w) return $("modes-row");
  return $("brush").closest(".toolbar");
}

// Inpaint chosen: the picture to paint on sized (sizeEditor) and brought into view with the mode's row and the tools
// above it (0.58 left it below the fold, to be scrolled to before painting), or the tools only (editorTop).
function showEditor() {
  sizeEditor();
  if ($("editor").hidden) intoView($("inpaint")); else intoView($("editor"), editorTop());
}

function clearMask() {
  const canvas = $("mask");
  context2d(canvas).clearRect(0, 0, canvas.width, canvas.height);
}

// Undo: the mask before each stroke, Clear or mask file; the picture (and the hole painted on it) before each Fill
// or Extend: a fill that came out badly is tried again (another seed) without painting its hole again.
const UNDO_STEPS = 20;

// `what`: the step's name, said when it is undone ("a stroke", "Clear", "the mask file").
function remember(picture, what) {
  const canvas = $("mask");
  if (!canvas.width) return;
  editor.history.push({ mask: context2d(canvas).getImageData(0, 0, canvas.width, canvas.height), picture, what });
  if (editor.history.length > UNDO_STEPS) editor.history.shift();
  updateButtons();
}

function undoInpaint() {
  if (state.busy) return;
  const step = editor.history.pop();
  if (!step) return;
  if (!step.picture) {
    context2d($("mask")).putImageData(step.mask, 0, 0);
    updateButtons();
    // said (0.63): 0.62 left the line before, "fill undone: ..." after a stroke undone after it
    sayInpaint(undoneLine(step.what, editor.history.length));
    return;
  }
  const history = editor.history, p = step.picture;  // the picture before: shown again, its hole painted
  editor.pendingMask = step.mask;
  if (p.shown) showResult(URL.createObjectURL(p.blob), p.shown.seed, p.blob, p.shown.what, p.maps, p.shown.name);
  else {
    setEditorPicture(p.blob, p.name, p.maps);
    showOwnPicture(p.blob, p.name);
  }
  if (p.grow) {  // that Extend, to try again: a size for the picture brought back
    [$("extend-height").value, $("extend-width").value] = p.grow.to;
    editor.growFrom = p.grow.from;
    keepFields();  // across a reload too (history.js)
  }
  editor.history = history;
  updateButtons();
  sayInpaint(`${p.undone} undone: the picture before it, with its hole`);
}

// A picture of the user's own that Undo brought back to paint on is the result again too (its tiling and Download
// PNG, under its own name), not the fill or extension undone.
function showOwnPicture(blob, name) {
  if (state.resultUrl) URL.revokeObjectURL(state.resultUrl);
  if (state.shown) for (const m of state.shown.maps) URL.revokeObjectURL(m.url);
  const url = URL.createObjectURL(blob);
  state.resultUrl = url;
  state.lastShown = null;  // not a result: a Fill of it is undone to this again
  state.resultTiles = false;
  state.shown = null;
  renderMaps();
  showPicture(url, "your picture", null, name, name);
  renderHistory();  // no recent result is the one shown now
  keepShown(null);  // nor after a reload
}

// Ctrl+Z (Cmd+Z) in Inpaint and Paint modes is their Undo, but in a text field (the browser's own undo of its text).
function onUndoKey(event) {
  if (event.key.toLowerCase() !== "z" || !(event.ctrlKey || event.metaKey) || event.shiftKey || event.altKey) return;
  if (event.target.closest("input:not([type=checkbox]):not([type=range]), select")) return;
  if (!$("inpaint").hidden) undoInpaint(); else if (!$("paint").hidden) undoPaint(); else return;
  event.preventDefault();
}

function maskPainted() {
  const canvas = $("mask");
  if (!canvas.width) return false;
  const pixels = context2d(canvas).getImageData(0, 0, canvas.width, canvas.height).data;
  for (let i = 3; i < pixels.length; i += 4) if (pixels[i] > 127) return true;
  return false;
}

function onClear() {
  if (maskPainted()) remember(null, "Clear");
  clearMask();
}

function brushPoint(event, canvas) {
  canvas = canvas || $("mask");
  const rect = canvas.getBoundingClientRect();
  return [(event.clientX - rect.left) * canvas.width / rect.width,
    (event.clientY - rect.top) * canvas.height / rect.height];
}

function paint(from, to) {
  const ctx = context2d($("mask"));
  ctx.globalCompositeOperation = $("erase").checked ? "destination-out" : "source-over";
  ctx.strokeStyle = ctx.fillStyle = "#ff00e6";  // shown at 60 % over the picture
  ctx.lineWidth = Number($("brush").value);
  ctx.lineCap = ctx.lineJoin = "round";
  ctx.beginPath();
  if (from[0] === to[0] && from[1] === to[1]) {  // a click: browsers draw no line of length 0
    ctx.arc(from[0], from[1], ctx.lineWidth / 2, 0, 2 * Math.PI);
    ctx.fill();
    return;
  }
  ctx.moveTo(from[0], from[1]);
  ctx.lineTo(to[0], to[1]);
  ctx.stroke();
}

function onBrushDown(event) {
  if (event.button !== 0 || !editor.blob) return;
  event.preventDefault();
  remember(null, "a stroke");
  $("mask").setPointerCapture(event.pointerId);
  editor.painting = true;
  editor.last = brushPoint(event);
  paint(editor.last, editor.last);
}

// A circle of the brush's size follows the pointer over the picture.
function moveCursor(event, canvas, cursor, brush) {
  canvas = canvas || $("mask");
  cursor = cursor || $("brush-cursor");
  const rect = canvas.getBoundingClientRect();
  const size = Number((brush || $("brush")).value) * rect.width / canvas.width;
  cursor.style.width = cursor.style.height = `${size}px`;
  cursor.style.left = `${event.clientX - rect.left}px`;
  cursor.style.top = `${event.clientY - rect.top}px`;
  cursor.hidden = false;
}

function onBrushMove(event) {
  moveCursor(event, null, null, null);
  if (!editor.painting) return;
  const point = brushPoint(event);
  paint(editor.last, point);
  editor.last = point;
}

function onBrushUp() {
  editor.painting = false;
  editor.last = null;
}

// The pixels of an image file as they are (no smoothing), or null (said why with `say`) when the browser cannot read
// it or it is not h x w: a mask painted elsewhere, the keyboard's way to one (painting needs a pointer).
async function filePixels(file, h, w, what, say) {
  let bitmap;
  try {
    bitmap = await createImageBitmap(file);
  } catch (e) {
    say(`the browser cannot read ${file.name}: use a PNG ${what}`, true);
    return null;
  }
  if (bitmap.height !== h || bitmap.width !== w) {
    say(`${file.name} is ${bitmap.height}x${bitmap.width}, not ${h}x${w}: use a ${what} of that size`, true);
    return null;
  }
  const canvas = document.createElement("canvas");
  canvas.width = w;
  canvas.height = h;
  const ctx = context2d(canvas);
  ctx.drawImage(bitmap, 0, 0);
  return ctx.getImageData(0, 0, w, h).data;
}

// A mask from a file: its white pixels (channel mean over half, as the API reads a mask) painted, the rest clear;
// the brush can add to it or erase.
async function onMaskFile(file) {
  if (!file) return;
  const canvas = $("mask");
  if (!editor.blob || !canvas.width) {
    sayInpaint("generate an image first, or use a picture of your own", true);
    return;
  }
  const pixels = await filePixels(file, canvas.height, canvas.width, "mask, white where the hole is", sayInpaint);
  if (!pixels) return;
  remember(null, `the mask ${file.name}`);
  const ctx = context2d(canvas), image = ctx.createImageData(canvas.width, canvas.height);
  for (let i = 0; i < pixels.length; i += 4) {
    if (pixels[i] + pixels[i + 1] + pixels[i + 2] > 1.5 * 255) image.data.set([255, 0, 230, 255], i);  // #ff00e6
  }
  ctx.putImageData(image, 0, 0);
  const grey = greyShare(pixels, canvas.width);  // a picture given as the mask: said, as tghop inpaint says it
  sayInpaint(withWarning(`the hole is ${file.name}'s white: Fill, or paint to change it`, grey > 0.2
    ? `${file.name} is not black and white: ${Math.round(100 * grey)}% of its pixels are grey or coloured (a ` +
      "picture?), and those lighter than mid-grey are taken as the hole; paint the hole white on black" : ""));
}

// The share of a mask's pixels (RGBA bytes, `w` wide; every other one each way) neither black nor white: their
// channels' mean within 15 % of black or white and their channels within 15 % of each other are, as
// tghop.inpaint.grey_share reads a mask (over 20 %: a picture, whose light pixels become the hole).
function greyShare(pixels, w) {
  const h = pixels.length / (4 * w), near = 0.15 * 255;
  let n = 0, other = 0;
  for (let y = 0; y < h; y += 2) {
    for (let x = 0; x < w; x += 2) {
      const i = 4 * (y * w + x), r = pixels[i], g = pixels[i + 1], b = pixels[i + 2];
      const spread = Math.max(r, g, b) - Math.min(r, g, b);
      if (!(Math.abs((r + g + b) / 3 - 127.5) > 127.5 - near && spread <= near)) other++;
      n++;
    }
  }
  return n ? other / n : 0;
}

// The mask as the API wants it: white where painted (more than half opaque), black elsewhere.
function maskBlob() {
  const canvas = $("mask");
  const w = canvas.width, h = canvas.height;
  if (!maskPainted()) return Promise.resolve(null);
  const out = document.createElement("canvas");
  out.width = w;
  out.height = h;
  const ctx = out.getContext("2d");
  ctx.drawImage(canvas, 0, 0);
  ctx.globalCompositeOperation = "source-in";
  ctx.fillStyle = "#fff";
  ctx.fillRect(0, 0, w, h);
  ctx.globalCompositeOperation = "destination-over";
  ctx.fillStyle = "#000";
  ctx.fillRect(0, 0, w, h);
  return new Promise((resolve) => out.toBlob(resolve, "image/png"));
}

// POST the editor's picture with the fields of `fields` (and `seed`, "" for a random one, and the tile of the inpaint
// toolbar) to /api/models/{id}/{path}: the answer, {blob, maps, used: the seed used, warning: the server's warning of
// it, or "" (X-Tghop-Warning: what reading the picture or mask said, e.g. a colour profile converted)}. `progress`:
// withProgress's options (the part of the bar it fills). `model`: {id, material}, the working model's by default (a
// strip of fills keeps the one it began with: a fit started meanwhile leaves the page without one until it ends);
// `picture`: {blob, name, maps}, the editor's by default (a strip's, the one it began with: a fill picked while the
// others come is the editor's picture then, and 0.60 filled the rest of the strip in it).
async function askPicture(path, fields, seed, progress, model = { id: state.modelId, material: state.material },
                          picture = editor) {
  const form = new FormData();
  form.append("image", picture.blob, picture.name);
  for (const [name, value, filename] of fields) {  // a file takes its name; a plain value has none
    if (filename === undefined) form.append(name, value); else form.append(name, value, filename);
  }
  if (seed !== "") form.append("seed", seed);
  form.append("tile", $("inpaint-tile").checked ? "true" : "false");
  if (model.material && picture.maps) {  // a material's result: every map filled alike
    for (const m of picture.maps.slice(1)) form.append(`map:${m.name}`, m.blob, `${m.name}.png`);
  }
  const url = `/api/models/${model.id}/${path}`;
  const response = await withProgress("inpaint-progress", (headers) => busyFetch(url, {
    method: "POST", body: form, headers: { Accept: GENERATION_HEADERS.Accept, ...headers },
  }), progress);
  if (!response.ok) throw new Error(await errorOf(response));
  const { blob, maps } = await answerOf(response);
  return { blob, maps, used: response.headers.get("X-Tghop-Seed"), warning: response.headers.get("X-Tghop-Warning")
    || "" };
}

// What Undo goes back to from a Fill or Extend of the picture now in the editor: that picture (the result shown, or a
// picture of the user's) and its hole.
function stepBefore(path, size) {
  const canvas = $("mask"), img = $("editor-base");
  return { mask: context2d(canvas).getImageData(0, 0, canvas.width, canvas.height), picture: {
    blob: editor.blob, name: editor.name, maps: editor.maps, undone: path === "inpaint" ? "fill" : "extend",
    shown: state.lastShown && state.lastShown.blob === editor.blob ? state.lastShown : null,
    grow: path === "extend" ? { to: size.map(String), from: [img.naturalHeight, img.naturalWidth] } : null } };
}

// A fill or extension (askPicture's answer) shown as the result, Undo going back to `before` after `history` (the
// steps before it). `pick`: a fills strip's run (keepResult: a second pick from it takes the first's place), whose
// `fill` k numbers the answer's file as tghop inpaint --count numbers fill k (OUT_k.png) and `model` its model.
function showFilled(answer, what, size, before, history, pick) {
  const model = pick ? pick.model : { id: state.modelId, stem: workingStem() };
  showResult(URL.createObjectURL(answer.blob), answer.used, answer.blob, what, answer.maps,
             { models: [model.stem], size, tile: $("inpaint-tile").checked,
               ...(answer.fill ? { fill: answer.fill } : {}), ...madeBy(model.id) }, pick);
  editor.history = [...history, before].slice(-UNDO_STEPS);
  updateButtons();  // Undo (a pick from a fills strip comes after its Fill)
}

// The editor's picture sent to `path` with `fields`, the answer shown as the result: the seed used and the server's
// warning of it (askPicture).
async function sendPicture(path, fields, what, size) {
  const answer = await askPicture(path, fields, $("inpaint-seed").value.trim());
  showFilled(answer, what, size, stepBefore(path, size), editor.history);
  return [answer.used, answer.warning];
}

// Fill with a count above 1 (tghop inpaint --count's fills to pick from): `count` fills of the same hole, as
// tghop inpaint --seed s --count N makes them (0.61): fill k is the k-th drawn from seed s (the server's field fill;
// fill 1 is a Fill of seed s), downloaded as OUT_k.png names it (0.60 made seeds s, s + 1, ..., named by seed); without
// a seed, fill 1's drawn seed goes on. In the strip under the picture, one bar for them all; fill 1 shown, a click on
// another shows it instead, Undo from any going back to the picture before with its hole. The strip goes as the 8
// seeds' does (another mode or model) and at the next Fill: while its fills are still coming that stops them
// (clearStrip; 0.60 went on adding them to the strip cleared, of the new model once one was fitted).
async function fillStrip(mask, count, size) {
  const before = stepBefore("inpaint", size), history = editor.history;
  const model = { id: state.modelId, material: state.material, stem: workingStem() };
  const picture = { blob: editor.blob, name: editor.name, maps: editor.maps };  // each fill's, whatever is picked
  const strip = $("strip"), run = { model, running: true };  // run: this strip's picks (keepResult)
  strip.dataset.model = model.id;
  strip.setAttribute("aria-label", `${count} fills to pick from`);  // a screen reader's name of the group (0.61: 0.60
  // said "eight seeds to pick from")
  editor.fills = run;
  const pick = (answer) => showFilled(answer, "inpainted", size, before, history, run);
  let seed = $("inpaint-seed").value.trim(), warned = "", shown = null;  // shown: fill 1's, picked once all came
  let k = 1;
  try {
    for (; k <= count; k++) {
      sayInpaint(`fill ${k} of ${count}`);
      const answer = await askPicture("inpaint", [["mask", mask, "mask.png"], ["fill", String(k)]], seed,
                                      { from: (k - 1) / count, to: k / count, label: `fill ${k}: ` }, model, picture);
      if (run.dropped) throw new DOMException("the strip was cleared", "AbortError");
      seed = answer.used;
      answer.fill = k;
      warned = warned || answer.warning;
      const img = addToStrip(strip, URL.createObjectURL(answer.blob), `fill ${k} of seed ${seed}`, seed,
                             () => pick(answer), `fill ${k}`);
      shown = shown || img;
      if (!$("inpaint").hidden) {  // the picture made room for the strip under it (a second row, on a phone)
        await img.decode().catch(() => {});  // its height known
        sizeEditor();
        if (k === 1) intoView(strip, editorTop());
      }
    }
  } catch (e) {
    const came = `${k === 2 ? "fill 1 is" : `fills 1 ${k === 3 ? "and" : "to"} ${k - 1} are`} under the picture, ` +
      "fill 1 shown (click one to pick it); Undo goes back to the picture before";
    if (!run.dropped && e.name === "AbortError" && shown) {  // stopped by its button: the fills that came kept, fill 1
      shown.click();  // shown as a finished strip's is (0.60 showed none of them, "stopped" said alone)
      return [null, withWarning(`stopped at fill ${k} of ${count}: ${came}`, warned)];
    }
    if (!run.dropped && shown) {  // an error after some came: those kept, fill 1 shown, as Stop does, and the error
      shown.click();  // said in the same line (0.61 kept them in the strip but showed none, the error alone)
      // with the server's warnings of the fills that came, as a finished or stopped strip says them (0.62 dropped them)
      throw new Error(withWarning(`fill ${k} of ${count} failed: ${e.message.replace(/\.$/, "")}; ${came}`, warned));
    }
    if (!run.dropped) throw e;  // stopped before any came, or an error before any: said as any Fill's
    return [null, `the fills stopped at fill ${k} of ${count}: another mode or model was chosen, and their strip went`];
  } finally {
    run.running = false;
  }
  if (run.dropped) return [null, "the fills' strip went: another mode or model was chosen"];  // as the last came
  shown.click();  // fill 1, marked chosen
  return [seed, warned];
}

function onFill() {
  if (!state.modelId || !editor.blob) return;
  const count = $("inpaint-count");
  if (!count.checkValidity()) { sayInpaint(fieldProblem(count), true); count.focus(); return; }  // said, not sent
  withBusy($("fill"), async () => {
    const mask = await maskBlob();
    if (!mask) { sayInpaint("paint the hole first: drag the brush over the picture", true); return; }
    clearStrip();  // the fills of a picture before
    const img = $("editor-base"), size = [img.naturalHeight, img.naturalWidth];
    if (Number(count.value) > 1) {
      const [seed, warning] = await fillStrip(mask, Number(count.value), size);
      if (seed === null) { sayInpaint(warning); return; }  // cleared while they came (clearStrip), or stopped
      sayInpaint(withWarning(`${count.value} fills of seed ${seed} under the picture, as tghop inpaint --seed ` +
        `${seed} --count ${count.value} makes them: click one to pick it (fill 1 is shown); Undo goes back to the ` +
        "picture before", warning));
      return;
    }
    sayInpaint("filling");
    const [used, warning] = await sendPicture("inpaint", [["mask", mask, "mask.png"]], "inpainted", size);
    sayInpaint(withWarning(`filled (seed ${used}): paint again to fill more, or download it`, warning));
  }, sayInpaint);
}

function onExtend() {
  if (!state.modelId || !editor.blob) return;
  withBusy($("extend-go"), async () => {
    clearStrip();  // the fills of a picture before
    const img = $("editor-base");
    const [ph, pw] = [img.naturalHeight, img.naturalWidth];
    const h = $("extend-height").value.trim() || String(ph);
    const w = $("extend-width").value.trim() || String(pw);
    if (Number(h) < ph || Number(w) < pw || (Number(h) === ph && Number(w) === pw)) {  // said, not sent
      sayInpaint(`give a height and width of at least the picture's ${ph}x${pw}, larger in one`, true);
      return;
    }
    sayInpaint("extending");
    const [used, warning] = await sendPicture("extend", [["size", `${h}x${w}`], ["anchor", $("extend-anchor").value]],
                                              "extended", [h, w]);
    // The fields go on to the next size, grown as much again: Extend pressed again is not refused as the picture's size
    const next = [2 * Number(h) - ph, 2 * Number(w) - pw].map(String);
    [$("extend-height").value, $("extend-width").value] = next;
    editor.growFrom = [Number(h), Number(w)];  // the picture just made
    keepFields();
    sayInpaint(withWarning(`extended to ${h}x${w} (seed ${used}): paint to fill, Extend again to grow it as much ` +
                           `again (to ${next.join("x")}), or download it`, warning));
  }, sayInpaint);
}

function onPicture(file) {
  if (!file) return;
  setEditorPicture(file, file.name);
}
