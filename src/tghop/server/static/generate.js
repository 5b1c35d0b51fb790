// tghop serve's page, sections 2 and 3 (Generate, Result): the generation settings, Generate and the
// strip of seeds, the result shown (a material's maps one by one) and tiled 3x3.
"use strict";

function generation(seed, size) {
  const body = {
    size: size || [Number($("height").value), Number($("width").value)],
    seed: seed,
    tile: $("tile").checked,
  };
  const refine = $("refine").value.trim();
  if ($("paper-gen").checked) body.paper = true;
  if (refine !== "") body.refine = Number(refine);
  const pool = $("n_patches").value.trim();
  if (pool !== "") body.n_patches = Number(pool);
  if (!$("quality").disabled && $("quality").value !== "default") body.quality = $("quality").value;
  return body;
}

// `id`: the model (the strip of seeds keeps the one it started with when another exemplar is picked meanwhile).
// `headers`: more of them (withProgress's job).
async function generate(body, id = state.modelId, headers = {}) {
  const response = await busyFetch(`/api/models/${id}/images`, {
    method: "POST", body: JSON.stringify(body), headers: { ...GENERATION_HEADERS, ...headers },
  });
  if (!response.ok) throw new Error(await errorOf(response));
  // X-Tghop-Warning: what reading the model's file warned of (a newer tghop's file), said once (onGenerate)
  return { ...(await answerOf(response)), warning: response.headers.get("X-Tghop-Warning") || "" };
}

// Shows a result; a material's (`maps`) with a choice of the map shown, each map downloadable. `name`: what
// names its file, {models: their stems, size, tile} (resultBase); the working model's at the size asked for.
// `name.of`: the models of a result of several ("cells + bricks"), said in its caption (the exemplar beside it
// is the working model's only). `pick`: the strip run a seed shown was picked from (history.js, keepResult). Whether
// it took the place of a recent result of the same model, settings and seed (keepResult).
function showResult(url, seed, blob, what, maps, name, pick) {
  if (state.resultUrl) URL.revokeObjectURL(state.resultUrl);
  if (state.shown) for (const m of state.shown.maps) if (m.url !== url) URL.revokeObjectURL(m.url);
  state.resultUrl = url;
  state.lastShown = { seed, blob, what, name };
  state.resultTiles = Boolean(name && name.tile);  // the tiling's caption says whether its seams are expected
  const base = resultBase(seed, what, name);
  const of = (name && name.of) || "";
  state.shown = maps ? {
    seed, what, base, of, maps: maps.map((m, i) => ({ ...m, url: i ? URL.createObjectURL(m.blob) : url })),
  } : null;
  renderMaps();
  showPicture(url, `${what || "result"}`, seed, `${base}.png`, of);
  if (blob) setEditorPicture(blob, `${base}.png`, maps);  // a material's maps are filled alike
  return keepResult(blob, maps, seed, what, name, pick);  // the recent results, side by side
}

// `seed` null: a picture of the user's own (no seed said).
function showPicture(url, what, seed, filename, of) {
  const img = $("result");
  state.caption = { what, seed, of };
  img.onload = () => {
    resultCaption();
    drawTiled(img);
  };
  img.src = url;
  img.hidden = false;
  const link = $("download-png");
  link.href = url;
  link.setAttribute("download", filename);
  link.hidden = false;
  if (typeof followResult === "function") followResult();  // paint.js: Paint's thumbnail of its result
}

// The result's caption: what it is, its size and seed, and the models of a result of several; a result of one model
// that is not the one the exemplar beside it goes with (another exemplar picked since, or an older result shown again)
// names it (0.59: "result: 256x256, seed 1 (made with builtin:bricks, not builtin:cells)"; 0.58 said nothing, and the
// cells exemplar stood beside a bricks result). Said again when the model changes (exemplarCaption).
function resultCaption() {
  const img = $("result"), parts = state.caption;
  if (!parts || img.hidden || !img.complete || !img.naturalWidth) return;
  const name = state.lastShown && state.lastShown.name, now = state.pendingName;
  const other = !parts.of && name && name.model && name.model !== state.modelId ?
    ` (made with ${name.by}${now && now !== name.by ? `, not ${now}` : ""})` : "";
  $("result-caption").textContent = `${parts.what}: ${img.naturalHeight}x${img.naturalWidth}` +
    (parts.seed === null ? "" : `, seed ${parts.seed}`) + (name && name.fill ? `, fill ${name.fill}` : "") +
    (parts.of ? ` (${parts.of})` : other);
  $("result-caption").hidden = false;
}

// What a result of the model `id` keeps of it (showResult's `name`): its id and name, for resultCaption.
function madeBy(id) {
  const working = state.working && state.working.modelId === id ? state.working.name : null;
  const listed = state.models.find((m) => m.id === id);
  return { model: id, by: working || (listed ? listed.name : "another model") };
}

// The maps of the material shown: one radio each (the picture, its tiling and Download PNG follow it),
// and Download all (the files as tghop synth names them: OUT.png, OUT_<suffix>.png: mapFile).
function renderMaps() {
  const group = $("maps-view"), shown = state.shown;
  group.textContent = "";
  group.hidden = $("download-maps").hidden = !shown;
  if (!shown) return;
  shown.maps.forEach((m, i) => {
    const label = document.createElement("label");
    const radio = document.createElement("input");
    radio.type = "radio";
    radio.name = "map-shown";
    radio.value = m.name;
    radio.checked = i === 0;
    radio.addEventListener("change", () => {
      if (radio.checked) {
        showPicture(m.url, `${shown.what || "result"} (${m.name})`, shown.seed, mapFile(shown, i), shown.of);
      }
    });
    label.append(radio, ` ${m.name}${m.depth === 16 ? " (16-bit)" : ""}`);
    group.append(label);
  });
}

// At most TILED_PIXELS (browsers leave a larger canvas blank): a large result's tiling is shown scaled down.
const TILED_PIXELS = 4096 * 4096;

function drawTiled(img) {
  const canvas = $("tiled");
  const scale = Math.min(1, Math.sqrt(TILED_PIXELS / (9 * img.naturalWidth * img.naturalHeight)));
  const w = Math.max(1, Math.floor(img.naturalWidth * scale)), h = Math.max(1, Math.floor(img.naturalHeight * scale));
  canvas.width = 3 * w;
  canvas.height = 3 * h;
  const ctx = context2d(canvas);
  for (let y = 0; y < 3; y++) for (let x = 0; x < 3; x++) ctx.drawImage(img, x * w, y * h, w, h);
  // A result not made tileable shows its edges as seams here, as it should: said, lest they look like a fault.
  const seams = state.resultTiles ? "(seams show here)" : "(not made tileable: its edges show as seams)";
  $("tiled-title").textContent = scale < 1 ? `Tiled 3\u00d73, shown at ${Math.round(100 * scale)} % ${seams}`
    : `Tiled 3\u00d73 ${seams}`;
  $("tiled-title").hidden = $("tiled-box").hidden = false;  // hidden until there is a result
  canvas.dataset.ready = "1";
}

// Generate's and 8 seeds' status, under their bar (section 1's, where it was, is out of sight once the results
// are scrolled to): an error is scrolled into view where it is not (the result or seeds waited for will not come).
function sayGenerate(text, isError) {
  const el = $("gen-message");
  sayIn(el, text, isError);
  if (isError) el.scrollIntoView({ block: "nearest" });  // "nearest": no scroll where it is in view
}

function onGenerate(event) {
  event.preventDefault();
  if (!state.modelId) return;
  withBusy($("go"), async () => {
    const seed = Number($("seed").value);
    sayGenerate("generating");
    const body = generation(seed);
    const { blob, maps, warning } = await withProgress("gen-progress",
                                                       (headers) => generate(body, state.modelId, headers));
    const again = showResult(URL.createObjectURL(blob), seed, blob, undefined, maps,
                             { models: [workingStem()], ...body, ...madeBy(state.modelId) });
    const notes = unsaid([warning]);
    // The same as a recent result: said, its entry now the first (0.59 added a second one)
    const same = again ? `seed ${seed} done: the same model, settings and seed as a recent result, the same image ` +
      "(one entry, now the first)" : "";
    sayGenerate(notes.length ? withWarning(same || `seed ${seed} done`, notes[0]) : same);
    await reveal($("result"));
  }, sayGenerate);
}

// Scrolls a picture just shown into view once it is drawn, where it is wholly out of sight (a result below the
// fold: the page looked as if Generate had done nothing); a picture partly in view stays where it is.
async function reveal(img) {
  try { await img.decode(); } catch (e) { return; }  // replaced meanwhile, or not drawn
  const rect = img.getBoundingClientRect();
  if (rect.top >= window.innerHeight || rect.bottom <= 0) img.scrollIntoView({ block: "nearest" });
}

// The strip of seeds is of one model, in View mode: cleared when the working model or the mode changes (it
// showed an earlier model's seeds). A strip still running goes on with its model (onStrip) and is kept.
// Its hint goes with it (it asked to click seeds no longer shown).
function clearStrip() {
  if (state.busyButton === $("strip-go")) return;
  const strip = $("strip"), fills = editor.fills;
  if (fills && fills.running && !fills.dropped) {  // a Fill's strip still coming: stopped (fillStrip)
    fills.dropped = true;
    if (state.abort) state.abort.abort();
  }
  for (const old of strip.querySelectorAll("img")) URL.revokeObjectURL(old.src);
  strip.textContent = "";
  delete strip.dataset.model;
  if ($("gen-message").textContent.startsWith(STRIP_HINT)) sayGenerate("");
}

const STRIP_HINT = "click a seed to pick it";

// A picture of the strip to pick from (the 8 seeds', a Fill's with a count), `url` its image: `name` its button's
// name (alt, and its title with what a click does), `seed` its caption (`caption`: another, a fill's "fill 2"); a
// click, Enter or Space marks it chosen and calls `onPick`. Its seed said once, as the button's name: the caption (for
// the eye) and the figure are hidden from a screen reader, the title's "seed N" replaced by what it does (each was
// read as "seed N" too). Returns the img.
function addToStrip(strip, url, name, seed, onPick, caption = `seed ${seed}`) {
  const figure = document.createElement("figure"), img = document.createElement("img");
  figure.setAttribute("role", "none");
  img.src = url;
  img.alt = name;
  img.title = `${name}: click to pick`;
  img.setAttribute("aria-description", "shows it as the result");
  img.dataset.seed = String(seed);
  img.tabIndex = 0;  // Enter or Space picks it too
  img.setAttribute("role", "button");
  img.addEventListener("click", () => {
    for (const other of strip.querySelectorAll("img")) other.classList.remove("chosen");
    img.classList.add("chosen");
    onPick();
  });
  img.addEventListener("keydown", (e) => {
    if (e.key === "Enter" || e.key === " ") { e.preventDefault(); img.click(); }
  });
  const under = document.createElement("figcaption");
  under.textContent = caption;
  under.setAttribute("aria-hidden", "true");
  figure.append(img, under);
  strip.append(figure);
  return img;
}

// The browser's own check of Generate's fields (a size over its max, an empty seed) refuses with a bubble only:
// the status says what is wrong now, not what an earlier action left there ("stopped"). `invalid`, caught for
// the first field refused.
function onInvalidField(event) {
  const input = event.target;
  if (input.form.querySelector(":invalid") === input) sayGenerate(fieldProblem(input), true);
}

function fieldProblem(input) {
  const label = input.closest("label"), name = label ? label.firstChild.textContent.trim() : input.id;
  const v = input.validity, range = input.max ? `from ${input.min} to ${input.max}` : `of at least ${input.min}`;
  if (v.valueMissing) return `give a ${name}, a number ${range}`;
  if (v.rangeOverflow) return `${name} ${input.value} is more than ${input.max}: give a number ${range}`;
  if (v.rangeUnderflow) return `${name} ${input.value} is less than ${input.min}: give a number ${range}`;
  if (v.badInput) return `the ${name} is not a number: give one ${range}`;
  return `${name}: ${input.validationMessage}`;
}

// A strip still running when the working model (or the mode) changes goes on with its model, and is cleared when it
// ends (clearStrip waits for it): its seeds are of a model that is no longer the working one.
function onStrip() {
  if (!state.modelId || !$("gen-form").reportValidity()) return;  // an empty seed was seed 0
  const id = state.modelId;
  const stale = () => !state.working || state.working.modelId !== id ||
    document.querySelector("input[name=mode]:checked").value !== "view";
  withBusy($("strip-go"), async () => {
    const strip = $("strip");
    for (const old of strip.querySelectorAll("img")) URL.revokeObjectURL(old.src);
    strip.textContent = "";
    strip.dataset.model = id;
    strip.setAttribute("aria-label", "eight seeds to pick from");  // a strip of fills names itself (fillStrip)
    const first = Number($("seed").value), stem = workingStem(), run = {};  // run: this strip's picks (keepResult)
    const made = madeBy(id);
    let warned = "";  // what reading the model's file warned of, not said yet (onGenerate), said with the hint
    // Every seed of the settings as they were when the strip began (0.61: 0.60 read the fields again at each seed, and
    // tileable or quality changed while the strip ran made the rest of it with them, a strip of mixed settings)
    const settings = generation(first, [Number($("height").value), Number($("width").value)]);
    for (let i = 0; i < 8; i++) {
      const seed = first + i, body = { ...settings, seed };
      sayGenerate(`seed ${seed} (${i + 1} of 8)`);
      const answer = await withProgress("gen-progress", (headers) => generate(body, id, headers),
                                        { from: i / 8, to: (i + 1) / 8, label: `seed ${seed}: ` });
      warned = warned || unsaid([answer.warning])[0] || "";
      const img = addToStrip(strip, URL.createObjectURL(answer.blob), `seed ${seed}`, seed, () => {
        $("seed").value = String(seed);
        keepFields();  // across a reload (history.js)
        showResult(URL.createObjectURL(answer.blob), seed, answer.blob, undefined, answer.maps,
                   { models: [stem], ...body, ...made }, run);
      });
      if (i === 0) reveal(img);  // the strip below the fold (no result shown yet, or a tall one)
    }
    if (!stale()) sayGenerate(warned ? withWarning(STRIP_HINT, warned) : STRIP_HINT);
  }, sayGenerate).then(() => {
    if (!stale() || !$("strip").dataset.model) return;
    clearStrip();
    if (!$("gen-message").classList.contains("error")) sayGenerate("");  // "seed 8 (8 of 8)": of seeds not shown
    if (state.working && state.modelId === state.working.modelId) say("model ready: generate below");
  });
}
