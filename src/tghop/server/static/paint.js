// tghop serve's page, the modes with several models: Paint (a guide painted with one colour per
// model), Remix and Morph (from model A to model B); the session's models, each with its colour.
"use strict";

// The most models painted or remixed at once.
const MAX_PICKED = 4;

// Paint mode's board: its labels are indices into state.models, its brush the colour chosen.
const guide = makeBoard("guide", "guide-cursor", "paint-brush", () => brushLabel());

function sayPaint(text, isError, onlyNew) {
  sayIn($("paint-message"), text, isError, onlyNew);
}

function sayMorph(text, isError, onlyNew) {
  sayIn($("morph-message"), text, isError, onlyNew);
}

// What Paint and Morph say while the page has fewer than two models (cleared when the second comes).
const PAINT_HINT = "fit or load a second model above to paint with two";
const MORPH_HINT = "fit or load a second model above: A and B";

function addSessionModel(id, name) {
  if (state.models.some((m) => m.id === id)) return;
  const index = state.models.length;
  const label = `${name || "model"} (${id.slice(0, 8)})`;
  // stem: its part of a file's name; material: whether it is one, when known (Morph takes texture models only)
  state.models.push({ id, name: label, stem: modelStem(name), material: id === state.modelId ? state.material : null,
    picked: pickedModels().length < MAX_PICKED });
  if (state.models.length === 2) {
    if ($("paint-message").textContent === PAINT_HINT) sayPaint("");
    if ($("morph-message").textContent === MORPH_HINT) sayMorph("");
  }
  renderModels();
  if (!$("morph-a").value) $("morph-a").value = String(index);
  if (index > 0 && $("morph-b").value === $("morph-a").value) $("morph-b").value = String(index);
  if (!$("morph").hidden && state.models.length > 1) morphPicked();  // a material picked as B: said
  if (!$("paint").hidden) paintPicked();  // a material picked with texture models: said
}

function pickedModels() {
  return state.models.map((m, index) => ({ ...m, index })).filter((m) => m.picked);
}

function renderModels() {
  const list = $("paint-models");
  list.textContent = "";
  state.models.forEach((m, index) => {
    const label = document.createElement("label");
    const box = document.createElement("input");
    box.type = "checkbox";
    box.checked = m.picked;
    box.dataset.index = String(index);
    box.addEventListener("change", () => {
      if (box.checked && pickedModels().length >= MAX_PICKED) {
        box.checked = false;
        sayPaint(`paint with at most ${MAX_PICKED} models: unpick one first`, true);
        return;
      }
      m.picked = box.checked;
      renderColours();
      paintPicked();
    });
    label.append(box, swatch(index), m.name);
    list.append(label);
  });
  for (const id of ["morph-a", "morph-b"]) {
    const select = $(id), old = select.value;
    select.textContent = "";
    state.models.forEach((m, index) => {
      const option = document.createElement("option");
      option.value = String(index);
      option.textContent = m.name;
      select.append(option);
    });
    if (old) select.value = old;
  }
  renderColours();
  updateButtons();
}

// One brush colour per picked model; the first picked is the background of a new canvas.
function renderColours() {
  const group = $("paint-colours"), old = brushLabel();
  group.textContent = "";
  for (const m of pickedModels()) {
    const label = document.createElement("label");
    const radio = document.createElement("input");
    radio.type = "radio";
    radio.name = "paint-colour";
    radio.value = String(m.index);
    radio.id = `paint-colour-${m.index}`;
    label.title = m.name;
    radio.addEventListener("change", () => { state.brushChosen = true; });
    label.append(radio, swatch(m.index), m.name.split(" (")[0]);
    group.append(label);
  }
  // The user's colour is kept; until they choose one, the brush is the second picked model's
  // (the first is the canvas's background, so painting with it showed nothing).
  const radios = group.querySelectorAll("input");
  const keep = state.brushChosen && [...radios].find((r) => Number(r.value) === old);
  if (keep) keep.checked = true; else if (radios.length) radios[radios.length > 1 ? 1 : 0].checked = true;
}

function brushLabel() {
  const chosen = document.querySelector("input[name=paint-colour]:checked");
  return chosen ? Number(chosen.value) : null;
}

// A new canvas at the output's size (the height and width of Generate), all the first picked model.
// Reset: a blank canvas of the output's size, the one before it (and its Undo) kept where it was of that size.
function resetGuide() {
  const before = guide.labels, history = guide.history, [h, w] = [guide.h, guide.w];
  resizeGuide(true);
  if (before && guide.h === h && guide.w === w) {
    guide.history = history;
    rememberBoard(guide, "Reset", before);
  }
  sayPaint("");
}

// Paint's Undo (its button, Ctrl+Z), said as Inpaint's is (0.63: 0.62 said nothing, the line before stayed).
function undoPaint() {
  const what = undoBoard(guide);
  if (what) sayPaint(undoneLine(what, guide.history.length));
}

function resizeGuide(force) {
  const h = Number($("height").value), w = Number($("width").value);
  if (!(h > 0 && w > 0 && h * w <= 4096 * 4096)) { sayPaint("set a height and width above first", true); return; }
  if (!force && guide.labels && guide.h === h && guide.w === w) return;
  const first = pickedModels()[0];
  resetBoard(guide, h, w, first ? first.index : 0);
  sizeGuide();
}

// The guide shown no larger (board.js enlarges a small one up to 4 times, 640 px) than lets the mode's row, Paint's
// tools and the whole canvas be seen at once while Paint is shown (roomFor; 0.59: at 1024x700 a 256x256 canvas ran
// 640 px below the fold under the tools). A canvas shown at its size stays so.
function sizeGuide() {
  const canvas = $("guide"), w = canvas.width, h = canvas.height;
  if ($("paint").hidden || !w || !h) return;
  canvas.style.width = `${Math.max(w, Math.min(4 * w, 640, roomFor($("guide-box"), w, h)))}px`;
}

// A file's bytes as a data: URL (what the API's guide fields take).
function dataUrl(file) {
  return new Promise((resolve, reject) => {
    const reader = new FileReader();
    reader.onload = () => resolve(reader.result);
    reader.onerror = () => reject(new Error(`the browser cannot read ${file.name}`));
    reader.readAsDataURL(file);
  });
}

// A guide from a file, read by the server as Generate's guide is (POST /api/guides/labels: tghop's guide_labels,
// one rule for both): its flat colours, sorted dark to light, are the picked models in their order; soft or JPEG
// edges are taken (each pixel of a blend goes to the nearest flat colour), and a guide of the canvas's shape but
// another size is scaled to it. Refused (another shape, another count of colours) in the server's words.
async function onGuideFile(file) {
  if (!file) return;
  const picked = pickedModels();
  if (picked.length < 2) { sayPaint("pick 2 to 4 models first: the guide's colours are theirs", true); return; }
  resizeGuide();
  if (!guide.labels) return;
  const [h, w] = [guide.h, guide.w];
  let answer;
  try {
    const body = JSON.stringify({ guide: await dataUrl(file), n_models: picked.length, size: [h, w] });
    const response = await fetch("/api/guides/labels",
                                 { method: "POST", headers: { "Content-Type": "application/json" }, body });
    if (!response.ok) { sayPaint(`${file.name}: ${await errorOf(response)}`, true); return; }
    answer = await response.json();
  } catch (e) {
    sayPaint(`${file.name}: ${e.message}`, true);
    return;
  }
  if (guide.h !== h || guide.w !== w || answer.size[0] !== h || answer.size[1] !== w) {
    sayPaint(`the canvas changed while ${file.name} was read: use it again`, true);
    return;
  }
  const labels = base64Bytes(answer.labels);
  rememberBoard(guide, `the guide file ${file.name}`);
  for (let i = 0; i < labels.length; i++) guide.labels[i] = picked[labels[i]].index;
  drawBoard(guide, 0, 0, guide.w, guide.h);
  sayPaint(withWarning(`the guide is ${file.name}: Generate, or paint to change it`, answer.notes.join("; ")));
}

// The guide as the API wants it: the picked models' grey levels, darkest for the first (a data: URL).
function guidePng(picked) {
  const used = new Set(guide.labels);
  const stray = [...used].find((k) => !picked.some((m) => m.index === k));
  if (stray !== undefined) {
    throw new Error(`the canvas has paint of ${state.models[stray].name}, which is not picked: ` +
                    "pick it or paint over it");
  }
  const unused = picked.find((m) => !used.has(m.index));
  if (unused) throw new Error(`paint some of ${unused.name} (its colour) or unpick it`);
  return boardPng(guide, new Map(picked.map((m, j) => [m.index, Math.round(255 * j / (picked.length - 1))])));
}

// The generation settings of a painted guide or a remix: each model's region is its own synthesis.
function severalSettings(body) {
  const one = generation(null);
  for (const name of ["tile", "refine", "n_patches", "paper", "quality"]) if (name in one) body[name] = one[name];
  return body;
}

// Models painted or remixed together are all texture models or all materials: why the picked ones are not
// (a material with a texture model; kinds not known yet are left to the server), or "".
function paintProblem() {
  const picked = pickedModels();
  const material = picked.find((m) => m.material === true), texture = picked.find((m) => m.material === false);
  if (!material || !texture) return "";
  return `${material.name} is a material and ${texture.name} a texture model: paint or remix all materials ` +
         "(with the same maps) or all texture models; unpick one of them";
}

// Paint's and Remix's buttons and message follow the models picked (a material with a texture model: off,
// and said why), as Morph's do.
function paintPicked() {
  const problem = paintProblem(), shown = $("paint-message").textContent;
  if (problem) sayPaint(problem, true, true);
  else if (shown.includes(" a texture model: paint or remix all ")) sayPaint("");
  updateButtons();
}

function onPaintGenerate(remix) {
  const picked = pickedModels();
  if (picked.length < 2 || paintProblem()) return;
  const bare = severalSettings({}).quality === "best" && picked.find((m) => m.patches === false);
  if (bare) {  // said, not sent (0.60: the server's 422 named it "models[0]", a name the page shows nowhere)
    sayPaint(`${bare.name} has no patch statistics for quality best (fitted with the paper's settings): choose ` +
             "quality default above, or unpick it", true);
    return;
  }
  withBusy($(remix ? "remix-go" : "paint-go"), async () => {
    const body = severalSettings({ models: picked.map((m) => m.id), seed: Number($("paint-seed").value) });
    if (remix) {
      body.size = [Number($("height").value), Number($("width").value)];
    } else {
      resizeGuide();
      body.guide = guidePng(picked);
      body.transition = Number($("transition").value);
    }
    sayPaint(remix ? "remixing" : "generating");
    const [blob, seed, maps, warning] = await withProgress(
      "paint-progress", (headers) => postImage("/api/images/guided", body, headers));
    const name = { models: picked.map((m) => m.stem), size: body.size || [guide.h, guide.w], tile: Boolean(body.tile),
      of: picked.map((m) => m.stem).join(" + ") };
    showResult(URL.createObjectURL(blob), seed, blob, remix ? "remix" : "painted", maps, name);
    showPainted(blob);
    sayPaint(withWarning(`done (seed ${seed}): the result is below, ${thumbSaid("paint-result", $("guide-box"))}`,
                         warning));
    await thumbInView("paint-result");  // under the canvas in a narrow window
  }, (text, isError) => sayPaint(pickedNamed(text, picked), isError));
}

// The server's message with each "models[i] (id's start)" it names said as the page names the model picked: its
// name (0.61; 0.60 showed "models[1] (3f2a91c0) has the maps ...", a name the page shows nowhere).
function pickedNamed(text, picked) {
  return text.replace(/models\[(\d+)\](?: \(([0-9a-f]{8})\))?/g, (whole, i, id) => {
    const m = picked[Number(i)];
    return m && (!id || m.id.startsWith(id)) ? `${m.name} (${m.id.slice(0, 8)})` : whole;
  });
}

// Paint's and Remix's last result as a thumbnail beside the canvas (0.61: it came below the canvas only, out of sight
// at 1024x700, "the result is below"), and (0.62) Co-occurrence's beside its edit's canvas; a click on it scrolls to
// the result. Each shown while that result is the one shown. `thumbs`: each figure's id to its result's blob and URL.
const thumbs = { "paint-result": { blob: null, url: null }, "cooc-result": { blob: null, url: null } };

function showThumb(id, blob) {
  const thumb = thumbs[id];
  if (thumb.url) URL.revokeObjectURL(thumb.url);
  thumb.blob = blob;
  thumb.url = URL.createObjectURL(blob);
  $(`${id}-img`).src = thumb.url;
  followResult();
}

function showPainted(blob) {
  showThumb("paint-result", blob);
}

// Called whenever the result shown changes (showPicture): each thumbnail goes with the result it is of.
function followResult() {
  for (const [id, thumb] of Object.entries(thumbs)) {
    $(id).hidden = !thumb.blob || !state.lastShown || state.lastShown.blob !== thumb.blob;
  }
}

// A thumbnail just shown, with its caption, scrolled into view where it is not wholly in view once drawn (under its
// canvas in a narrow window; 0.61 scrolled only where it was wholly out of sight, and at 400x800 left it cut at the
// window's edge).
async function thumbInView(id) {
  try { await $(`${id}-img`).decode(); } catch (e) { return; }  // replaced meanwhile, or not drawn
  if (!$(id).hidden) $(id).scrollIntoView({ block: "nearest" });
}

// A thumbnail's click: the result itself scrolled into view.
function goToPainted() {
  const result = $("result");
  result.scrollIntoView({ block: "nearest" });
  // whole: a result whose foot lies between two pixels (a help cut to its lines above it, 0.63) ended a fraction of
  // a pixel under the window's foot, the scroll being whole pixels
  const below = result.getBoundingClientRect().bottom - window.innerHeight;
  if (below > 0 && below < 1) window.scrollBy(0, 1);
}

// What a mode's "done" line says of its result shown as a thumbnail `id` beside `canvas`: "its thumbnail beside the
// canvas (click it to go there)", or under it (a narrow window).
function thumbSaid(id, canvas, name = "the canvas") {
  const place = placeBy($(id), canvas);
  return `its thumbnail ${place ? `${place} ${name} ` : ""}(click it to go there)`;
}

// A morph goes between two texture models, or two materials with the same maps (0.60, as tghop morph takes them: every
// map morphed alike; 0.59 took texture models only): why the A and B picked cannot be morphed (a material with a
// texture model; kinds not known yet, and the maps, are left to the server), or "".
function morphProblem() {
  const [a, b] = ["morph-a", "morph-b"].map((id) => state.models[Number($(id).value)]);
  if (!a || !b || typeof a.material !== "boolean" || typeof b.material !== "boolean" || a.material === b.material) {
    return "";
  }
  const [material, texture] = a.material ? [["A", a], ["B", b]] : [["B", b], ["A", a]];
  return `${material[0]}, ${material[1].name}, is a material and ${texture[0]}, ${texture[1].name}, a texture ` +
         "model: morph two materials (with the same maps) or two texture models; pick another A or B";
}

// The patch size of a model whose summary has not come (the fit's default): the page fits no other.
const DEFAULT_PATCH_SIZE = 32;

// Morph's height is at least a patch of A's and B's (a lower strip is refused by the server, 422): their
// summaries' patch size (patchSize, showSummary), the default until one comes (the server's message tells of
// a smaller one).
function morphMinimum() {
  const sizes = ["morph-a", "morph-b"].map((id) => state.models[Number($(id).value)])
    .map((m) => (m && m.patchSize) || DEFAULT_PATCH_SIZE);
  $("morph-height").min = String(Math.max(...sizes));
}

// Morph's button, message and least height follow the A and B picked (a material: off, and said why).
function morphPicked() {
  morphMinimum();
  const problem = morphProblem(), shown = $("morph-message").textContent;
  if (problem) sayMorph(problem, true, true); else if (shown.includes(", is a material and ")) sayMorph("");
  updateButtons();
}

function onMorph() {
  const a = state.models[Number($("morph-a").value)], b = state.models[Number($("morph-b").value)];
  if (!a || !b || morphProblem()) return;
  // The fields checked here, as Generate's are by its form (fieldProblem): not sent to be refused
  morphMinimum();
  const bad = ["morph-height", "morph-width", "morph-seed"].map($).find((input) => !input.checkValidity());
  if (bad) {
    const low = bad.id === "morph-height" && bad.validity.rangeUnderflow;
    sayMorph(fieldProblem(bad) + (low ? " (a morph is at least a patch of its models tall)" : ""), true);
    bad.focus();
    return;
  }
  withBusy($("morph-go"), async () => {
    const body = {
      a: a.id, b: b.id, seed: Number($("morph-seed").value),
      size: [Number($("morph-height").value), Number($("morph-width").value)],
    };
    const one = generation(null);
    for (const name of ["refine", "n_patches", "paper"]) if (name in one) body[name] = one[name];
    sayMorph("morphing");
    const [blob, seed, maps] = await withProgress("morph-progress",
                                                  (headers) => postImage("/api/images/morph", body, headers));
    showResult(URL.createObjectURL(blob), seed, blob, "morph", maps,  // two materials': every map (0.60)
               { models: [a.stem, "to", b.stem], size: body.size, tile: false, of: `${a.stem} to ${b.stem}` });
    await reveal($("result"));  // scrolled to where wholly out of sight (0.61: a narrow window's was below the fold)
    const place = placeBy($("result"), $("exemplar"));  // 0.60 said "the strip is below" beside the exemplar too
    sayMorph(`done (seed ${seed}): the strip is ${place ? `${place} the exemplar` : "below"}`);
  }, sayMorph);
}

// Where `el` is shown from `ref`: "beside" it (a row of their own: the result and the exemplar in a wide window) or
// "under" it (a narrow window); null where `ref` is not shown.
function placeBy(el, ref) {
  const a = el.getBoundingClientRect(), b = ref.getBoundingClientRect();
  if (ref.hidden || !b.height) return null;
  return a.top < b.bottom - 1 ? "beside" : "under";
}
