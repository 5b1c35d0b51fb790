// tghop serve's page: its state and what every part of it uses (app.js says which file does what).
"use strict";

const $ = (id) => document.getElementById(id);
const state = { modelId: null, job: null, events: null, resultUrl: null, exemplarUrl: null, busy: false,
  resultTiles: false, models: [], pendingName: null, brushChosen: false, abort: null, busyButton: null, fitRequest: 0,
  // A whole material: the map files to fit with the exemplar (section 1), the last exemplar
  // fitted (refitted when the maps change), and the maps of the result shown (section 3).
  // `mapsHeld`: the maps listed wait for the next exemplar (none yet, or theirs is another size than the last one's);
  // `heldOff`: the exemplar they are not of ({source, other}: holdMaps), picked again without them; `mapsChecking`:
  // maps added whose size is being read (setMapFiles), which an exemplar picked meanwhile takes; `mapsOffer`: maps
  // "Use them with ..." gives the exemplar shown (fit.js, offerMaps).
  mapFiles: [], mapsHeld: false, heldOff: null, mapsChecking: null, mapsOffer: null, source: null, material: false,
  shown: null,
  // Whether the material's albedo has patch statistics (its summary's patch_levels; null: not known yet): setMaterial.
  patches: null,
  // The working model, what a refused or cancelled fit or a refused model file goes back to (fit.js,
  // setWorking), and the running fit's way back to it (its `undo`, for cancelFit).
  working: null, fitUndo: null,
  // A built-in browsed to by keyboard in the closed menu, fitted once the choice settles ({name, timer}; fit.js).
  browsed: null,
  // The result shown, as showResult was given it ({seed, blob, what, name}): what Inpaint's Undo shows again.
  lastShown: null,
  // The result's caption's parts ({what, seed, of}: showPicture), put together by resultCaption (generate.js).
  caption: null,
  // What the server said of reading model files (an upload's notes, a summary's, a generation's X-Tghop-Warning)
  // and the page has said: each said once (unsaid).
  notesSaid: new Set() };
// The inpaint editor: its picture (a blob of its own, so that it outlives the result's URL)
// and the brush's last point while painting.
// `history`: what Undo goes back to, the latest last (inpaint.js); `pendingMask`: a mask put back once the
// picture loads; `fills`: the last strip of fills' run (inpaint.js, fillStrip: whether it is still coming).
const editor = { blob: null, url: null, name: "picture.png", last: null, painting: false, maps: null, history: [],
  pendingMask: null, fills: null, growFrom: null };  // growFrom: the picture's size Extend's fields were set for

// The 2d context of a canvas whose pixels are read back (getImageData: the mask at each Fill, the boards and
// the tiling by the tests): made for it, or Chromium warns that it is slow. The first getContext sets it.
function context2d(canvas) {
  return canvas.getContext("2d", { willReadFrequently: true });
}

// A status line (say, sayGenerate, ...): an error is an alert, which a screen reader says at once; the rest a
// status, said when it is done speaking. The role is set before the text, so that the text is said in it.
// `onlyNew`: a check redone whenever the models change (inpaintHint, paintPicked, morphPicked) leaves a line that
// says the same as it is, untouched: its text put again was said again, an alert each time.
function sayIn(el, text, isError, onlyNew) {
  if (onlyNew && el.textContent === (text || "") && el.classList.contains("error") === Boolean(isError)) return;
  el.setAttribute("role", isError ? "alert" : "status");
  el.textContent = text || "";
  el.classList.toggle("error", Boolean(isError));
}

function say(text, isError) {
  sayIn($("message"), text, isError);
}

// When `el` (a button turned off or hidden) has the keyboard's focus, it goes to `to`: else to the page's body,
// from where a screen reader says nothing and Tab starts over.
function keepFocus(el, to) {
  if (document.activeElement === el) to.focus();
}

async function errorOf(response) {
  try {
    const body = await response.json();
    if (body && body.error) return body.error;
  } catch (e) { /* not JSON */ }
  return `${response.status} ${response.statusText}`;
}

function updateButtons() {
  // Not while the model's kind is unknown (state.material null), nor whether a material's albedo has patch statistics
  // (state.patches null): its summary says whether quality applies (setMaterial)
  $("go").disabled = $("strip-go").disabled = state.busy || !state.modelId || state.material === null ||
    (state.material === true && state.patches === null);
  // A material fills every map of one of its results: not a picture without maps, nor before its kind is known
  $("fill").disabled = $("extend-go").disabled = state.busy || !state.modelId || !editor.blob ||
    state.material === null || (state.material && !editor.maps);
  $("undo").disabled = state.busy || !editor.history.length;
  $("paint-undo").disabled = typeof guide === "undefined" || !guide.history.length;  // paint.js
  $("paint-go").disabled = $("remix-go").disabled = state.busy || pickedModels().length < 2 ||
    (typeof paintProblem === "function" && paintProblem() !== "");  // paint.js: a material with a texture model
  $("morph-go").disabled = state.busy || state.models.length < 2 ||
    (typeof morphProblem === "function" && morphProblem() !== "");  // paint.js: a material as A or B
  if (typeof updateCoocButtons === "function") updateCoocButtons();  // cooc.js
  if (state.busyButton) state.busyButton.disabled = false;  // it reads Stop
}

// Runs `work` with the other buttons disabled; meanwhile `button` reads Stop and aborts the request
// (state.abort's signal), and the server stops that work at its next progress report.
async function withBusy(button, work, report) {
  if (state.busy) return;
  state.busy = true;
  state.abort = new AbortController();
  const old = button.textContent;
  const stop = (e) => { e.preventDefault(); e.stopImmediatePropagation(); state.abort.abort(); };
  button.textContent = "Stop";
  state.busyButton = button;
  updateButtons();
  button.addEventListener("click", stop, true);
  try {
    await work();
  } catch (e) {
    if (e.name === "AbortError") (report || say)("stopped"); else (report || say)(e.message, true);
  } finally {
    for (const box of document.querySelectorAll(".gen-progress")) box.hidden = true;  // withProgress's bars
    button.removeEventListener("click", stop, true);
    button.textContent = old;
    state.busy = false;
    state.abort = state.busyButton = null;
    updateButtons();
  }
}

// fetch() that the Stop of withBusy aborts (answeredFetch).
function busyFetch(url, options) {
  return answeredFetch(url, { ...options, signal: state.abort ? state.abort.signal : undefined });
}

// fetch() whose lack of any answer (the server stopped, its terminal closed) is said with the fix (noAnswer), not as
// the browser's bare "Failed to fetch" (0.62); a Stop's abort stays an AbortError.
async function answeredFetch(url, options) {
  try {
    return await fetch(url, options);
  } catch (e) {
    if (e.name === "AbortError") throw e;  // Stop
    throw new Error(noAnswer(e));
  }
}

// What an Undo says: the step undone (`what`), and whether it was the last (`left`: the steps still to undo).
function undoneLine(what, left) {
  return `${what} undone${left ? "" : " (nothing more to undo)"}`;
}

// A request the server did not answer (fetch's TypeError `e`): said with what to do.
function noAnswer(e) {
  return `the server did not answer (${e.message}): is tghop serve still running? Start it again, then try again`;
}

// A generation's request headers: a material's maps come as multipart (Response.formData() reads it:
// no base64 to decode, a third smaller); a texture's image is a PNG whatever is asked.
const GENERATION_HEADERS = { "Content-Type": "application/json", Accept: "multipart/form-data, application/json" };

// A generation's answer: a texture's PNG ({blob, maps: null}), or a material's maps, the albedo first
// ({blob: the albedo's, maps: [{name, suffix, depth, blob}]}; suffix: what the map's file adds to the
// result's, as tghop synth names it): multipart (a part "_meta" of JSON, then a PNG file per map, named
// by it) or JSON of base64 PNGs.
async function answerOf(response) {
  const kind = response.headers.get("Content-Type") || "";
  if (kind.startsWith("multipart/form-data")) {
    const form = await response.formData();
    const maps = JSON.parse(form.get("_meta")).maps.map((m) => ({
      name: m.name, suffix: m.suffix, depth: m.depth, blob: form.get(m.name),
    }));
    return { blob: maps[0].blob, maps };
  }
  if (!kind.startsWith("application/json")) return { blob: await response.blob(), maps: null };
  const maps = (await response.json()).maps.map((m) => ({
    name: m.name, suffix: m.suffix, depth: m.depth, blob: new Blob([base64Bytes(m.png)], { type: "image/png" }),
  }));
  return { blob: maps[0].blob, maps };
}

// Base64 text -> its bytes, in a plain loop: Uint8Array.from(text, fn) calls a function per byte, many
// times slower on a large material's maps.
function base64Bytes(text) {
  const binary = atob(text), bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
  return bytes;
}

// The answer's image, seed, maps (materials painted or remixed) and the server's warning of it, or "" (its
// X-Tghop-Warning: a guide or a label map of another size scaled to the size asked; docs/serve.md).
async function postImage(url, body, headers) {
  const response = await busyFetch(url, { method: "POST", body: JSON.stringify(body),
    headers: { ...GENERATION_HEADERS, ...headers } });
  if (!response.ok) throw new Error(await errorOf(response));
  const { blob, maps } = await answerOf(response);
  return [blob, response.headers.get("X-Tghop-Seed"), maps, response.headers.get("X-Tghop-Warning") || ""];
}

// The notes (lines) not said yet (state.notesSaid), now counted as said.
function unsaid(notes) {
  const fresh = notes.filter((note) => note && !state.notesSaid.has(note));
  for (const note of fresh) state.notesSaid.add(note);
  return fresh;
}

// A result's status with the server's warning of it (postImage's) after it, said as the command line says one.
function withWarning(text, warning) {
  return warning ? `${text}. Warning: ${warning}` : text;
}

// A progress bar's label beside it ("patch refine 88 %"), which is also the value a screen reader says of the bar
// (the percentage alone without it, the stage untold).
function showStage(bar, label, text) {
  label.textContent = text;
  bar.setAttribute("aria-valuetext", text);
}

// The widest a picture of w x h to paint on (Inpaint's, Paint's, Co-occurrence's edit), in `box`, may be shown for
// the mode's row (or `from`), the tools between it and the picture, and the whole picture to be seen in the window at
// once (0.59; PAINT_MARGIN under it), and `below` pixels under it (Inpaint's strip of fills, 0.61).
function roomFor(box, w, h, from = $("modes-row"), below = 0) {
  const above = box.getBoundingClientRect().top - from.getBoundingClientRect().top;
  return Math.floor((window.innerHeight - above - PAINT_MARGIN - below) * w / h);
}

// Pixels left under a picture to paint on (its border, and a little of the page).
const PAINT_MARGIN = 12;

// A mode chosen: `box` (its picture to paint on) brought into view with the mode's row (or `from`) at the top, where
// it is not wholly in view.
function intoView(box, from = $("modes-row")) {
  const rect = box.getBoundingClientRect();
  if (rect.top < 0 || rect.bottom > window.innerHeight) from.scrollIntoView({ block: "start" });
}

// A job's bar just shown, and the status line under it, brought into sight where they are below the fold (0.64: at
// 1024x700 after "model ready", and at 400x800 for Morph and Fill, the button read Stop and its bar and "generating"
// came out of sight under it, the page looking stuck for the seconds the image took). Never scrolled up: a bar above
// the window (Co-occurrence's, over its section) stays where it is, the artist at the canvas they work on.
function barInSight(box) {
  const status = box.nextElementSibling && box.nextElementSibling.getAttribute("role") === "status"
    ? box.nextElementSibling : box;
  const below = status.getBoundingClientRect().bottom + 8 - window.innerHeight;
  if (below > 0 && box.getBoundingClientRect().top >= 0) window.scrollBy(0, below);
}

// A new job id for a generation: 32 hex digits (the request's X-Tghop-Job header; docs/serve.md, "Jobs").
function newJobId() {
  return [...crypto.getRandomValues(new Uint8Array(16))].map((b) => b.toString(16).padStart(2, "0")).join("");
}

// How often a generation's progress is asked for, in milliseconds.
const PROGRESS_POLL_MS = 200;

// Runs `request(headers)`, a generation whose headers name a new job, and meanwhile shows that job's progress
// (GET /api/jobs/{job}) in the bar `boxId` (a .gen-progress: a <progress> and its label) until the answer comes;
// withBusy hides the bar when its work ends. `from`, `to`: the part of the bar this generation fills (the strip's
// 8 seeds fill one bar), `label` goes before the stage.
async function withProgress(boxId, request, { from = 0, to = 1, label = "" } = {}) {
  const job = newJobId(), box = $(boxId), bar = box.querySelector("progress"), text = box.querySelector("span");
  let ended = false, timer = null;
  box.dataset.job = job;  // for scripts and tests
  if (from === 0 || box.hidden) bar.value = from;
  showStage(bar, text, `${label}waiting`);
  const shown = !box.hidden;
  box.hidden = false;
  if (!shown) barInSight(box);
  const poll = async () => {
    try {
      // "unknown" (not 404, a console error) until the server has read the request as far as its job header
      const response = await fetch(`/api/jobs/${job}?expected=1`);
      const snap = response.ok ? await response.json() : null;
      if (snap && snap.state !== "unknown" && !ended) {
        bar.value = Math.max(bar.value, from + (to - from) * snap.progress);  // it never goes back
        const stage = snap.state === "queued" ? "waiting" : snap.stage || "starting";
        showStage(bar, text, `${label}${stage} ${Math.round(100 * bar.value)} %`);
      }
    } catch (e) { /* the next poll asks again */ }
    if (!ended) timer = setTimeout(poll, PROGRESS_POLL_MS);
  };
  timer = setTimeout(poll, PROGRESS_POLL_MS);
  try {
    const answer = await request({ "X-Tghop-Job": job });
    bar.value = to;
    return answer;
  } finally {
    ended = true;
    clearTimeout(timer);
  }
}
