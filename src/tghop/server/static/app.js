// tghop serve's page: the HTTP API under /api (docs/serve.md), nothing else.
"use strict";

const $ = (id) => document.getElementById(id);
const state = { modelId: null, job: null, events: null, resultUrl: null, exemplarUrl: null, busy: false,
  models: [], pendingName: null, brushChosen: false, abort: null, busyButton: null, fitRequest: 0,
  // A whole material: the map files to fit with the exemplar (section 1), the last exemplar
  // fitted (refitted when the maps change), and the maps of the result shown (section 3).
  mapFiles: [], source: null, material: false, shown: null };
// The inpaint editor: its picture (a blob of its own, so that it outlives the result's URL)
// and the brush's last point while painting.
const editor = { blob: null, url: null, name: "picture.png", last: null, painting: false, maps: null };

function say(text, isError) {
  const el = $("message");
  el.textContent = text || "";
  el.classList.toggle("error", Boolean(isError));
}

async function errorOf(response) {
  try {
    const body = await response.json();
    if (body && body.error) return body.error;
  } catch (e) { /* not JSON */ }
  return `${response.status} ${response.statusText}`;
}

function setExemplar(url) {
  if (state.exemplarUrl && state.exemplarUrl.startsWith("blob:")) URL.revokeObjectURL(state.exemplarUrl);
  state.exemplarUrl = url;
  const img = $("exemplar");
  if (url) { img.src = url; img.hidden = false; } else { img.removeAttribute("src"); img.hidden = true; }
}

function updateButtons() {
  // Not while the model's kind is unknown (state.material null): its summary says whether quality applies
  $("go").disabled = $("strip-go").disabled = state.busy || !state.modelId || state.material === null;
  $("fill").disabled = $("extend-go").disabled = state.busy || !state.modelId || !editor.blob;
  $("paint-go").disabled = $("remix-go").disabled = state.busy || pickedModels().length < 2;
  $("morph-go").disabled = state.busy || state.models.length < 2;
  if (typeof updateCoocButtons === "function") updateCoocButtons();  // cooc.js
  if (state.busyButton) state.busyButton.disabled = false;  // it reads Stop
}

// `material`: whether the model is a material, when known (a fit's: it sent maps); else null until
// its summary says (an uploaded file).
function setModel(id, material = null) {
  state.modelId = id;
  setMaterial(material);
  if (id) addSessionModel(id, state.pendingName);
  updateButtons();
  offerDownload($("download-model"), id && `/api/models/${id}/file`, id && `tghop-${id.slice(0, 12)}.npz`);
}

// A download link for `href` saved as `name` (hidden when href is empty).
function offerDownload(link, href, name) {
  link.hidden = !href;
  if (!href) return;
  link.href = href;
  link.setAttribute("download", name);
}

async function showSummary(id) {
  const response = await fetch(`/api/models/${id}`);
  const s = response.ok ? await response.json() : { error: await errorOf(response) };
  if (state.modelId !== id) return;  // another model took its place meanwhile: not its summary
  if (s.error) { say(s.error, true); return; }
  const dims = Object.entries(s.dims).map(([k, v]) => `${k}=${v}`).join(", ");
  const [h, w, c] = s.exemplar_shape;
  const scaled = s.params && s.params.scale !== 1 ? ` (resampled by ${s.params.scale})` : "";
  const maps = s.material ? s.material.maps : null;
  const what = maps ? "material" : "model";
  $("summary").textContent =
    `${what} ${id.slice(0, 12)}: exemplar ${h}x${w}${scaled}, ${c} channel${c > 1 ? "s" : ""}; ` +
    `${s.n_parameters.total.stored.toLocaleString()} parameters; layout ${s.layout ? "on" : "off"}\n${dims}` +
    (maps ? `\nmaps: ${maps.map((m) => `${m.name}${m.normal ? " (normal)" : ""}, ${m.depth}-bit`).join("; ")}` : "");
  $("summary").hidden = false;
  setMaterial(Boolean(maps));
}

// A material has no patch statistics: the quality preset does not apply to it. `on` null: not known yet
// (an uploaded file until its summary comes): the menu is off too, as best would be a 422 for a material.
function setMaterial(on) {
  state.material = on;
  $("quality").disabled = on !== false;
  $("quality").title = on ? "a material has no patch statistics: quality best does not apply"
    : on === null ? "off until the page knows whether the model is a material (its summary)" : "";
  updateButtons();
}

// ------------------------------------------------------------------ fitting
function fitFields() {
  const form = new FormData();
  if (!$("layout").checked) form.append("layout_factor", "none");
  if ($("paper-fit").checked) form.append("paper", "true");
  for (const name of ["scale", "n_clusters", "n_codewords", "stride", "max_patches"]) {
    const value = $(name).value.trim();
    if (value) form.append(name, value);
  }
  for (const file of state.mapFiles) form.append(`map:${mapName(file.name)}`, file, file.name);
  return form;
}

// A map's name from its file's: the stem, as tghop fit --maps names it (other characters as "_").
function mapName(filename) {
  const stem = filename.replace(/\.[^.]*$/, "").replace(/[^A-Za-z0-9._-]/g, "_").replace(/^[^A-Za-z0-9]+/, "");
  return stem.slice(0, 64) || "map";
}

// Why the map files cannot be one material's (their names, as the server would refuse them), or "".
function mapsProblem(files) {
  const seen = new Map([["albedo", "the exemplar"]]);
  for (const file of files) {
    const name = mapName(file.name), key = name.toLowerCase();
    if (key === "albedo") return `${file.name} would be the map "albedo", the exemplar's name: rename the file`;
    if (seen.has(key)) return `${seen.get(key)} and ${file.name} both name the map "${name}": rename one of them`;
    seen.set(key, file.name);
  }
  return "";
}

// The map files chosen (none: a texture model); the exemplar fitted last is fitted again with them.
function setMapFiles(files) {
  if (!useMapFiles(files)) return;
  if (state.source && state.source.file) fitFile(state.source.file);
  else if (state.source && state.source.builtin) fitBuiltin(state.source.builtin);
  else if (state.mapFiles.length) say("now pick or drop the exemplar (the albedo): it is fitted with these maps");
}

// The map files to fit with the next exemplar, listed; false (said, the maps chosen before kept) when
// their names clash.
function useMapFiles(files) {
  files = [...files];  // before the input is emptied: its FileList is live
  const problem = mapsProblem(files);
  $("maps").value = "";  // choosing the same files again is a change
  if (problem) { say(problem, true); return false; }
  state.mapFiles = files;
  const names = state.mapFiles.map((f) => mapName(f.name));
  $("maps-list").textContent = names.length ? `maps: ${names.join(", ")}` : "";
  $("maps-clear").hidden = !names.length;
  return true;
}

// A name that says albedo (albedo, diff, diffuse, color, colour, basecolor, as a word of the file's name).
const ALBEDO_NAME = /(^|[^a-z])(albedo|diff|diffuse|(base)?colou?r)([^a-z]|$)/i;

// Several files dropped at once are a material: the exemplar (its albedo) is the one named like an
// albedo when exactly one is, else the first; the others are its maps. A model file goes on its own.
function dropFiles(files) {
  const model = files.find((f) => /\.(npz|pt)$/i.test(f.name));
  if (model) {
    say(`${files.length} files dropped: drop the model file ${model.name} on its own (nothing was used)`, true);
    return;
  }
  const named = files.filter((f) => ALBEDO_NAME.test(f.name.replace(/\.[^.]*$/, "")));
  const albedo = named.length === 1 ? named[0] : files[0];
  const maps = files.filter((f) => f !== albedo);
  if (!useMapFiles(maps)) return;
  fitFile(albedo);
  say(`${files.length} files dropped: ${albedo.name} is the exemplar (the albedo), the others its maps ` +
      `(${maps.map((f) => mapName(f.name)).join(", ")}); "Add maps..." changes them`);
}

function stopEvents() {
  if (state.events) { state.events.close(); state.events = null; }
}

// A fit still running when another exemplar or a model file replaces it is cancelled: the page forgets it.
function dropRunningFit() {
  stopEvents();
  if (state.job && !$("fit-status").hidden && !$("fit-status").dataset.state) {
    fetch(`/api/jobs/${state.job}`, { method: "DELETE" }).catch(() => {});
  }
  state.job = null;
}

async function startFit(form) {
  dropRunningFit();
  const request = ++state.fitRequest;  // a later fit or upload asked for meanwhile replaces this one
  setModel(null);
  $("summary").hidden = true;
  $("fit-status").hidden = false;
  delete $("fit-status").dataset.state;  // set again when this fit ends
  $("progress").value = 0;
  $("stage").textContent = "sending";
  $("cancel").disabled = false;
  say("");
  let response;
  try {
    response = await fetch("/api/models", { method: "POST", body: form });
  } catch (e) {
    if (request !== state.fitRequest) return;
    say(`the server did not answer (${e.message})`, true);
    $("fit-status").hidden = true;
    return;
  }
  if (!response.ok) {
    const error = await errorOf(response);
    if (request !== state.fitRequest) return;
    say(error, true);
    $("fit-status").hidden = true;
    return;
  }
  const { id, job } = await response.json();
  const material = [...form.keys()].some((k) => k.startsWith("map:"));  // a fit with maps makes a material
  if (request !== state.fitRequest) {  // replaced while its answer came: withdrawn, as dropRunningFit does
    fetch(`/api/jobs/${job}`, { method: "DELETE" }).catch(() => {});
    return;
  }
  state.job = job;
  $("fit-status").dataset.job = job;  // for scripts and tests: GET /api/jobs/{job}
  follow(id, job, material);
}

function follow(id, job, material) {
  const events = new EventSource(`/api/jobs/${job}/events`);
  state.events = events;
  const update = (snap) => {
    $("progress").value = snap.progress;
    $("stage").textContent = snap.state !== "running" ? snap.state
      : snap.stage ? `${snap.stage} ${Math.round(100 * snap.progress)} %` : "starting";
  };
  events.addEventListener("progress", (e) => update(JSON.parse(e.data)));
  events.addEventListener("end", (e) => {
    const snap = JSON.parse(e.data);
    stopEvents();
    update(snap);
    $("cancel").disabled = true;
    $("fit-status").dataset.state = snap.state;
    if (snap.state === "done") {
      $("progress").value = 1;
      setModel(id, material);
      say("model ready: generate below");
      showSummary(id);
    } else if (snap.state === "cancelled") {
      say("fit cancelled");
    } else {
      say(snap.error || "the fit failed", true);
    }
    if (snap.state !== "done") $("builtin").value = "";  // so that choosing the same one again fits it
  });
  events.onerror = () => {
    if (state.events !== events) return;
    // The browser reconnects by itself; if the job is gone, say so.
    fetch(`/api/jobs/${job}`).then(async (r) => {
      if (!r.ok && state.events === events) { stopEvents(); say(await errorOf(r), true); }
    }).catch(() => {});
  };
}

async function cancelFit() {
  if (!state.job) return;
  $("cancel").disabled = true;
  const response = await fetch(`/api/jobs/${state.job}`, { method: "DELETE" });
  if (!response.ok) { say(await errorOf(response), true); return; }
  if ((await response.json()).askers > 0) {  // another page asked for the same model: it fits on for that page
    stopEvents();
    $("fit-status").dataset.state = "cancelled";
    $("stage").textContent = "cancelled";
    $("builtin").value = "";
    say("fit cancelled here (it goes on for another page that asked for the same model)");
  }
}

function fitFile(file) {
  if (!file) return;
  state.source = { file };
  state.pendingName = file.name + (state.mapFiles.length ? ` + ${state.mapFiles.length} maps` : "");
  $("builtin").value = "";
  setExemplar(URL.createObjectURL(file));
  const form = fitFields();
  form.append("image", file, file.name);
  startFit(form);
}

function fitBuiltin(name) {
  if (!name) return;
  state.source = { builtin: name };
  state.pendingName = `builtin:${name}` + (state.mapFiles.length ? ` + ${state.mapFiles.length} maps` : "");
  setExemplar(`/api/builtins/${name}.png`);
  const form = fitFields();
  form.append("builtin", name);
  startFit(form);
}

async function uploadModel(file) {
  if (!file) return;
  dropRunningFit();
  state.fitRequest++;  // a fit whose answer is still on its way is replaced
  state.source = null;
  $("fit-status").hidden = true;
  setExemplar(null);
  setModel(null);
  say(`uploading ${file.name}`);
  const response = await fetch("/api/models/upload", {
    method: "POST", body: file, headers: { "Content-Type": "application/octet-stream" },
  });
  if (!response.ok) { say(await errorOf(response), true); return; }
  const { id } = await response.json();
  state.pendingName = file.name;
  setModel(id);
  say(`model ${file.name} loaded: generate below`);
  await showSummary(id);
  if (state.modelId === id && state.material) say(`material ${file.name} loaded: generate below (every map)`);
}

// ------------------------------------------------------------------ generating
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

// A generation's request headers: a material's maps come as multipart (Response.formData() reads it:
// no base64 to decode, a third smaller); a texture's image is a PNG whatever is asked.
const GENERATION_HEADERS = { "Content-Type": "application/json", Accept: "multipart/form-data, application/json" };

async function generate(body) {
  const response = await busyFetch(`/api/models/${state.modelId}/images`, {
    method: "POST", body: JSON.stringify(body), headers: GENERATION_HEADERS,
  });
  if (!response.ok) throw new Error(await errorOf(response));
  return answerOf(response);
}

// A generation's answer: a texture's PNG ({blob, maps: null}), or a material's maps, the albedo first
// ({blob: the albedo's, maps: [{name, depth, blob}]}): multipart (a part "_meta" of JSON, then a PNG
// file per map, named by it) or JSON of base64 PNGs.
async function answerOf(response) {
  const kind = response.headers.get("Content-Type") || "";
  if (kind.startsWith("multipart/form-data")) {
    const form = await response.formData();
    const maps = JSON.parse(form.get("_meta")).maps.map((m) => ({
      name: m.name, depth: m.depth, blob: form.get(m.name),
    }));
    return { blob: maps[0].blob, maps };
  }
  if (!kind.startsWith("application/json")) return { blob: await response.blob(), maps: null };
  const maps = (await response.json()).maps.map((m) => ({
    name: m.name, depth: m.depth, blob: new Blob([base64Bytes(m.png)], { type: "image/png" }),
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

// Shows a result; a material's (`maps`) with a choice of the map shown, each map downloadable.
function showResult(url, seed, blob, what, maps) {
  if (state.resultUrl) URL.revokeObjectURL(state.resultUrl);
  if (state.shown) for (const m of state.shown.maps) if (m.url !== url) URL.revokeObjectURL(m.url);
  state.resultUrl = url;
  const base = what ? `tghop-${what}-seed${seed}` : `tghop-seed${seed}`;
  state.shown = maps ? {
    seed, what, base, maps: maps.map((m, i) => ({ ...m, url: i ? URL.createObjectURL(m.blob) : url })),
  } : null;
  renderMaps();
  showPicture(url, `${what || "result"}`, seed, `${base}.png`);
  if (blob) setEditorPicture(blob, `tghop-seed${seed}.png`, maps);  // a material's maps are filled alike
}

function showPicture(url, what, seed, filename) {
  const img = $("result");
  img.onload = () => {
    $("result-caption").textContent = `${what}: ${img.naturalHeight}x${img.naturalWidth}, seed ${seed}`;
    drawTiled(img);
  };
  img.src = url;
  img.hidden = false;
  const link = $("download-png");
  link.href = url;
  link.setAttribute("download", filename);
  link.hidden = false;
}

// The maps of the material shown: one radio each (the picture, its tiling and Download PNG follow it),
// and Download all (the files as tghop synth names them: OUT.png, OUT_<map>.png).
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
      if (radio.checked) showPicture(m.url, `${shown.what || "result"} (${m.name})`, shown.seed, mapFile(shown, i));
    });
    label.append(radio, ` ${m.name}${m.depth === 16 ? " (16-bit)" : ""}`);
    group.append(label);
  });
}

function mapFile(shown, i) {
  return i ? `${shown.base}_${shown.maps[i].name}.png` : `${shown.base}.png`;
}

// One download of every map: a ZIP of the PNGs as tghop synth names them (several downloads at once
// made browsers ask leave for each).
async function downloadMaps() {
  const shown = state.shown;
  if (!shown) return;
  const zip = await zipOf(shown.maps.map((m, i) => ({ name: mapFile(shown, i), blob: m.blob })));
  const link = document.createElement("a");
  link.href = URL.createObjectURL(zip);
  link.download = `${shown.base}.zip`;
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(link.href), 60_000);
}

// CRC-32 (IEEE, as ZIP takes it) of bytes, by a table.
const CRC_TABLE = (() => {
  const table = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xEDB88320 ^ (c >>> 1) : c >>> 1;
    table[n] = c >>> 0;
  }
  return table;
})();

function crc32(bytes) {
  let c = 0xFFFFFFFF;
  for (let i = 0; i < bytes.length; i++) c = CRC_TABLE[(c ^ bytes[i]) & 0xFF] ^ (c >>> 8);
  return (c ^ 0xFFFFFFFF) >>> 0;
}

// A ZIP archive of [{name, blob}], stored (PNGs are compressed already; ZIP's own format, APPNOTE
// 4.3: a local header and the data per file, then the central directory and its end record).
async function zipOf(files) {
  const parts = [], central = [];
  let offset = 0;
  for (const f of files) {
    const data = new Uint8Array(await f.blob.arrayBuffer());
    const name = new TextEncoder().encode(f.name);
    const crc = crc32(data);
    const local = new DataView(new ArrayBuffer(30));
    const entry = new DataView(new ArrayBuffer(46));
    local.setUint32(0, 0x04034b50, true);  // local file header
    entry.setUint32(0, 0x02014b50, true);  // central directory header
    entry.setUint16(4, 20, true);  // made by: version 2.0
    for (const [view, at] of [[local, 4], [entry, 6]]) {
      view.setUint16(at, 20, true);  // needed: version 2.0; flags 0, method 0 (stored), time 0 follow
      view.setUint16(at + 8, 0x21, true);  // date 1980-01-01
      view.setUint32(at + 10, crc, true);
      view.setUint32(at + 14, data.length, true);  // sizes, compressed and not
      view.setUint32(at + 18, data.length, true);
      view.setUint16(at + 22, name.length, true);
    }
    entry.setUint32(42, offset, true);  // where its local header is
    parts.push(local, name, data);
    central.push(entry, name);
    offset += 30 + name.length + data.length;
  }
  const size = central.reduce((sum, part) => sum + part.byteLength, 0);
  const end = new DataView(new ArrayBuffer(22));
  end.setUint32(0, 0x06054b50, true);  // end of central directory
  end.setUint16(8, files.length, true);
  end.setUint16(10, files.length, true);
  end.setUint32(12, size, true);
  end.setUint32(16, offset, true);
  return new Blob([...parts, ...central, end], { type: "application/zip" });
}

// At most TILED_PIXELS (browsers leave a larger canvas blank): a large result's tiling is shown scaled down.
const TILED_PIXELS = 4096 * 4096;

function drawTiled(img) {
  const canvas = $("tiled");
  const scale = Math.min(1, Math.sqrt(TILED_PIXELS / (9 * img.naturalWidth * img.naturalHeight)));
  const w = Math.max(1, Math.floor(img.naturalWidth * scale)), h = Math.max(1, Math.floor(img.naturalHeight * scale));
  canvas.width = 3 * w;
  canvas.height = 3 * h;
  const ctx = canvas.getContext("2d");
  for (let y = 0; y < 3; y++) for (let x = 0; x < 3; x++) ctx.drawImage(img, x * w, y * h, w, h);
  $("tiled-title").textContent = scale < 1 ? `Tiled 3\u00d73, shown at ${Math.round(100 * scale)} % (seams show here)`
    : "Tiled 3\u00d73 (seams show here)";
  canvas.dataset.ready = "1";
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
    button.removeEventListener("click", stop, true);
    button.textContent = old;
    state.busy = false;
    state.abort = state.busyButton = null;
    updateButtons();
  }
}

// fetch() that the Stop of withBusy aborts.
function busyFetch(url, options) {
  return fetch(url, { ...options, signal: state.abort ? state.abort.signal : undefined });
}

function onGenerate(event) {
  event.preventDefault();
  if (!state.modelId) return;
  withBusy($("go"), async () => {
    const seed = Number($("seed").value);
    say("generating");
    const { blob, maps } = await generate(generation(seed));
    showResult(URL.createObjectURL(blob), seed, blob, undefined, maps);
    say("");
  });
}

function onStrip() {
  if (!state.modelId || !$("gen-form").reportValidity()) return;  // an empty seed was seed 0
  withBusy($("strip-go"), async () => {
    const strip = $("strip");
    for (const old of strip.querySelectorAll("img")) URL.revokeObjectURL(old.src);
    strip.textContent = "";
    const first = Number($("seed").value);
    const [h, w] = [Number($("height").value), Number($("width").value)];
    for (let i = 0; i < 8; i++) {
      const seed = first + i;
      say(`seed ${seed} (${i + 1} of 8)`);
      const answer = await generate(generation(seed, [h, w]));
      const url = URL.createObjectURL(answer.blob);
      const figure = document.createElement("figure");
      const img = document.createElement("img");
      img.src = url;
      img.alt = `seed ${seed}`;
      img.title = `seed ${seed}: click to pick`;
      img.dataset.seed = String(seed);
      img.tabIndex = 0;  // Enter or Space picks it too
      img.setAttribute("role", "button");
      img.addEventListener("click", async () => {
        for (const other of strip.querySelectorAll("img")) other.classList.remove("chosen");
        img.classList.add("chosen");
        $("seed").value = String(seed);
        showResult(URL.createObjectURL(answer.blob), seed, answer.blob, undefined, answer.maps);
      });
      img.addEventListener("keydown", (e) => {
        if (e.key === "Enter" || e.key === " ") { e.preventDefault(); img.click(); }
      });
      const caption = document.createElement("figcaption");
      caption.textContent = `seed ${seed}`;
      figure.append(img, caption);
      strip.append(figure);
    }
    say("click a seed to pick it");
  });
}

// ------------------------------------------------------------------ inpainting
function sayInpaint(text, isError) {
  const el = $("inpaint-message");
  el.textContent = text || "";
  el.classList.toggle("error", Boolean(isError));
}

function setMode(mode) {
  const inpaint = mode === "inpaint";
  document.body.classList.toggle("inpaint", inpaint);
  $("inpaint").hidden = !inpaint;
  $("paint").hidden = mode !== "paint";
  $("morph").hidden = mode !== "morph";
  $("cooc").hidden = mode !== "cooc";
  if (mode === "cooc") coocShown();
  if (inpaint && state.material && !editor.maps) {
    sayInpaint("this model is a material: Fill and Extend fill every map of one of its results; generate first", true);
  } else if (inpaint && !editor.blob) sayInpaint("generate an image first, or use a picture of your own");
  if (mode === "paint") {
    resizeGuide();
    if (state.models.length < 2) sayPaint("fit or load a second model above to paint with two");
  }
  if (mode === "morph" && state.models.length < 2) sayMorph("fit or load a second model above: A and B");
}

// The picture to paint on: the latest result, or a picture the user chose.
// `maps`: a material result's maps (the albedo first), sent with the picture to Fill and Extend.
function setEditorPicture(blob, name, maps) {
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
    clearMask();
    // Small pictures are shown larger (up to 3 times, at most 640 pixels wide) to paint on.
    $("editor").style.width = `${Math.max(w, Math.min(3 * w, 640))}px`;
    $("editor").hidden = false;
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
  sayInpaint("");
}

function clearMask() {
  const canvas = $("mask");
  canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height);
}

function brushPoint(event, canvas) {
  canvas = canvas || $("mask");
  const rect = canvas.getBoundingClientRect();
  return [(event.clientX - rect.left) * canvas.width / rect.width,
    (event.clientY - rect.top) * canvas.height / rect.height];
}

function paint(from, to) {
  const ctx = $("mask").getContext("2d");
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

// The mask as the API wants it: white where painted (more than half opaque), black elsewhere.
function maskBlob() {
  const canvas = $("mask");
  const w = canvas.width, h = canvas.height;
  const pixels = canvas.getContext("2d").getImageData(0, 0, w, h).data;
  let painted = false;
  for (let i = 3; i < pixels.length; i += 4) if (pixels[i] > 127) { painted = true; break; }
  if (!painted) return Promise.resolve(null);
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

// POST the editor's picture with the fields of `fields` (and the seed and tile of the inpaint
// toolbar) to /api/models/{id}/{path}; the answer becomes the result. Returns the seed used.
async function sendPicture(path, fields, what) {
  const seed = $("inpaint-seed").value.trim();
  const form = new FormData();
  form.append("image", editor.blob, editor.name);
  for (const [name, value, filename] of fields) {  // a file takes its name; a plain value has none
    if (filename === undefined) form.append(name, value); else form.append(name, value, filename);
  }
  if (seed !== "") form.append("seed", seed);
  form.append("tile", $("inpaint-tile").checked ? "true" : "false");
  if (state.material && editor.maps) {  // a material's result: every map filled alike
    for (const m of editor.maps.slice(1)) form.append(`map:${m.name}`, m.blob, `${m.name}.png`);
  }
  const response = await busyFetch(`/api/models/${state.modelId}/${path}`, {
    method: "POST", body: form, headers: { Accept: GENERATION_HEADERS.Accept },
  });
  if (!response.ok) throw new Error(await errorOf(response));
  const { blob, maps } = await answerOf(response);
  const used = response.headers.get("X-Tghop-Seed");
  showResult(URL.createObjectURL(blob), used, blob, what, maps);
  return used;
}

function onFill() {
  if (!state.modelId || !editor.blob) return;
  withBusy($("fill"), async () => {
    const mask = await maskBlob();
    if (!mask) { sayInpaint("paint the hole first: drag the brush over the picture", true); return; }
    sayInpaint("filling");
    const used = await sendPicture("inpaint", [["mask", mask, "mask.png"]], "inpainted");
    sayInpaint(`filled (seed ${used}): paint again to fill more, or download it`);
  }, sayInpaint);
}

function onExtend() {
  if (!state.modelId || !editor.blob) return;
  withBusy($("extend-go"), async () => {
    const img = $("editor-base");
    const [ph, pw] = [img.naturalHeight, img.naturalWidth];
    const h = $("extend-height").value.trim() || String(ph);
    const w = $("extend-width").value.trim() || String(pw);
    if (Number(h) < ph || Number(w) < pw || (Number(h) === ph && Number(w) === pw)) {  // said, not sent
      sayInpaint(`give a height and width of at least the picture's ${ph}x${pw}, larger in one`, true);
      return;
    }
    sayInpaint("extending");
    const used = await sendPicture("extend", [["size", `${h}x${w}`], ["anchor", $("extend-anchor").value]],
                                   "extended");
    sayInpaint(`extended to ${h}x${w} (seed ${used}): paint to fill, extend again, or download it`);
  }, sayInpaint);
}

function onPicture(file) {
  if (!file) return;
  setEditorPicture(file, file.name);
}

// ------------------------------------------------------------------ several models: paint, remix, morph
// Every model fitted or loaded on this page (state.models) has a brush colour of its own.
const PALETTE = ["#e6194b", "#3cb44b", "#4363d8", "#ffe119", "#911eb4", "#f58231", "#42d4f4", "#f032e6"];
const MAX_PICKED = 4;
// A board: a canvas with one label per pixel, drawn in the palette's colours and painted by
// hand (not with the canvas's antialiased strokes), so every pixel is exactly one label's.
// Paint mode's guide (labels: indices into state.models) is one; the co-occurrence edit's is another.
function makeBoard(canvasId, cursorId, brushId, labelOf) {
  return { canvas: canvasId, cursor: cursorId, brush: brushId, labelOf, labels: null, h: 0, w: 0, last: null,
    painting: false };
}
const guide = makeBoard("guide", "guide-cursor", "paint-brush", () => brushLabel());

function sayPaint(text, isError) {
  const el = $("paint-message");
  el.textContent = text || "";
  el.classList.toggle("error", Boolean(isError));
}

function sayMorph(text, isError) {
  const el = $("morph-message");
  el.textContent = text || "";
  el.classList.toggle("error", Boolean(isError));
}

function colourOf(index) { return PALETTE[index % PALETTE.length]; }

function swatch(index) {
  const el = document.createElement("span");
  el.className = "swatch";
  el.style.background = colourOf(index);
  return el;
}

function addSessionModel(id, name) {
  if (state.models.some((m) => m.id === id)) return;
  const index = state.models.length;
  const label = `${name || "model"} (${id.slice(0, 8)})`;
  state.models.push({ id, name: label, picked: pickedModels().length < MAX_PICKED });
  renderModels();
  if (!$("morph-a").value) $("morph-a").value = String(index);
  if (index > 0 && $("morph-b").value === $("morph-a").value) $("morph-b").value = String(index);
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
      updateButtons();
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
function resizeGuide(force) {
  const h = Number($("height").value), w = Number($("width").value);
  if (!(h > 0 && w > 0 && h * w <= 4096 * 4096)) { sayPaint("set a height and width above first", true); return; }
  if (!force && guide.labels && guide.h === h && guide.w === w) return;
  const first = pickedModels()[0];
  resetBoard(guide, h, w, first ? first.index : 0);
}

// A new blank board of h x w pixels, all label `fill`, shown larger when small (up to 4 times, at most 640 px wide).
function resetBoard(b, h, w, fill) {
  b.h = h;
  b.w = w;
  b.labels = new Uint8Array(h * w).fill(fill);
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
  const ctx = $(b.canvas).getContext("2d");
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
  const x0 = Math.max(0, Math.floor(Math.min(from[0], to[0]) - r)), x1 = Math.min(b.w, Math.ceil(Math.max(from[0], to[0]) + r));
  const y0 = Math.max(0, Math.floor(Math.min(from[1], to[1]) - r)), y1 = Math.min(b.h, Math.ceil(Math.max(from[1], to[1]) + r));
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

// The guide as the API wants it: the picked models' grey levels, darkest for the first (a data: URL).
function guidePng(picked) {
  const used = new Set(guide.labels);
  const stray = [...used].find((k) => !picked.some((m) => m.index === k));
  if (stray !== undefined) throw new Error(`the canvas has paint of ${state.models[stray].name}, which is not picked: pick it or paint over it`);
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

async function postImage(url, body) {
  const response = await busyFetch(url, { method: "POST", body: JSON.stringify(body), headers: GENERATION_HEADERS });
  if (!response.ok) throw new Error(await errorOf(response));
  const { blob, maps } = await answerOf(response);
  return [blob, response.headers.get("X-Tghop-Seed"), maps];  // maps: materials painted or remixed
}

function onPaintGenerate(remix) {
  const picked = pickedModels();
  if (picked.length < 2) return;
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
    const [blob, seed, maps] = await postImage("/api/images/guided", body);
    showResult(URL.createObjectURL(blob), seed, blob, remix ? "remix" : "painted", maps);
    sayPaint(`done (seed ${seed}): the result is below`);
  }, sayPaint);
}

function onMorph() {
  const a = state.models[Number($("morph-a").value)], b = state.models[Number($("morph-b").value)];
  if (!a || !b) return;
  withBusy($("morph-go"), async () => {
    const body = {
      a: a.id, b: b.id, seed: Number($("morph-seed").value),
      size: [Number($("morph-height").value), Number($("morph-width").value)],
    };
    const one = generation(null);
    for (const name of ["refine", "n_patches", "paper"]) if (name in one) body[name] = one[name];
    sayMorph("morphing");
    const [blob, seed] = await postImage("/api/images/morph", body);
    showResult(URL.createObjectURL(blob), seed, blob, "morph");
    sayMorph(`done (seed ${seed}): the strip is below`);
  }, sayMorph);
}

// ------------------------------------------------------------------ wiring
async function init() {
  const select = $("builtin");
  try {
    const api = await (await fetch("/api")).json();
    for (const name of api.builtins) {
      const option = document.createElement("option");
      option.value = name;
      option.textContent = `builtin:${name}`;
      select.append(option);
    }
  } catch (e) {
    say("the server's API did not answer", true);
  }
  select.addEventListener("change", () => fitBuiltin(select.value));
  $("file").addEventListener("change", (e) => fitFile(e.target.files[0]));
  $("model-file").addEventListener("change", (e) => uploadModel(e.target.files[0]));
  $("maps").addEventListener("change", (e) => setMapFiles(e.target.files));
  $("maps-clear").addEventListener("click", () => setMapFiles([]));
  $("download-maps").addEventListener("click", downloadMaps);
  $("cancel").addEventListener("click", cancelFit);
  $("gen-form").addEventListener("submit", onGenerate);
  $("strip-go").addEventListener("click", onStrip);
  for (const radio of document.querySelectorAll("input[name=mode]")) {
    radio.addEventListener("change", () => { if (radio.checked) setMode(radio.value); });
  }
  $("brush").addEventListener("input", () => { $("brush-size").textContent = `${$("brush").value} px`; });
  $("clear").addEventListener("click", clearMask);
  $("fill").addEventListener("click", onFill);
  $("extend-go").addEventListener("click", onExtend);
  $("picture").addEventListener("change", (e) => onPicture(e.target.files[0]));
  const mask = $("mask");
  mask.addEventListener("pointerdown", onBrushDown);
  mask.addEventListener("pointermove", onBrushMove);
  mask.addEventListener("pointerup", onBrushUp);
  mask.addEventListener("pointercancel", onBrushUp);
  mask.addEventListener("pointerleave", () => { $("brush-cursor").hidden = true; });
  wireBoard(guide);
  $("paint-brush").addEventListener("input", () => { $("paint-brush-size").textContent = `${$("paint-brush").value} px`; });
  $("paint-reset").addEventListener("click", () => { resizeGuide(true); sayPaint(""); });
  for (const id of ["height", "width"]) {
    $(id).addEventListener("change", () => { if (!$("paint").hidden) resizeGuide(); });
  }
  $("paint-go").addEventListener("click", () => onPaintGenerate(false));
  $("remix-go").addEventListener("click", () => onPaintGenerate(true));
  $("morph-go").addEventListener("click", onMorph);
  $("zoom").addEventListener("change", (e) => document.body.classList.toggle("zoom", e.target.checked));
  const drop = $("drop");
  drop.addEventListener("keydown", (e) => {  // Enter or Space on the drop zone itself: the file chooser
    if (e.target === drop && (e.key === "Enter" || e.key === " ")) { e.preventDefault(); $("file").click(); }
  });
  drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    const files = [...e.dataTransfer.files];
    if (files.length > 1) { dropFiles(files); return; }
    const file = files[0];
    if (!file) return;
    const name = file.name.toLowerCase();
    if (name.endsWith(".npz")) uploadModel(file); else if (name.endsWith(".pt")) uploadCooc(file); else fitFile(file);
  });
  document.body.dataset.ready = "1";
}

document.addEventListener("DOMContentLoaded", init);
