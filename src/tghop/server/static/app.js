// tghop serve's page: the HTTP API under /api (docs/serve.md), nothing else.
"use strict";

const $ = (id) => document.getElementById(id);
const state = { modelId: null, job: null, events: null, resultUrl: null, exemplarUrl: null, busy: false };
// The inpaint editor: its picture (a blob of its own, so that it outlives the result's URL)
// and the brush's last point while painting.
const editor = { blob: null, url: null, name: "picture.png", last: null, painting: false };

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
  $("go").disabled = $("strip-go").disabled = state.busy || !state.modelId;
  $("fill").disabled = state.busy || !state.modelId || !editor.blob;
}

function setModel(id) {
  state.modelId = id;
  updateButtons();
  const link = $("download-model");
  if (id) {
    link.href = `/api/models/${id}/file`;
    link.setAttribute("download", `tghop-${id.slice(0, 12)}.npz`);
    link.hidden = false;
  } else {
    link.hidden = true;
  }
}

async function showSummary(id) {
  const response = await fetch(`/api/models/${id}`);
  if (!response.ok) { say(await errorOf(response), true); return; }
  const s = await response.json();
  const dims = Object.entries(s.dims).map(([k, v]) => `${k}=${v}`).join(", ");
  const [h, w, c] = s.exemplar_shape;
  $("summary").textContent =
    `model ${id.slice(0, 12)}: exemplar ${h}x${w}, ${c} channel${c > 1 ? "s" : ""}; ` +
    `${s.n_parameters.total.stored.toLocaleString()} parameters; layout ${s.layout ? "on" : "off"}\n${dims}`;
  $("summary").hidden = false;
}

// ------------------------------------------------------------------ fitting
function fitFields() {
  const form = new FormData();
  if (!$("layout").checked) form.append("layout_factor", "none");
  if ($("paper-fit").checked) form.append("paper", "true");
  for (const name of ["n_clusters", "n_codewords", "stride", "max_patches"]) {
    const value = $(name).value.trim();
    if (value) form.append(name, value);
  }
  return form;
}

function stopEvents() {
  if (state.events) { state.events.close(); state.events = null; }
}

async function startFit(form) {
  stopEvents();
  setModel(null);
  $("summary").hidden = true;
  $("fit-status").hidden = false;
  $("progress").value = 0;
  $("stage").textContent = "sending";
  $("cancel").disabled = false;
  say("");
  let response;
  try {
    response = await fetch("/api/models", { method: "POST", body: form });
  } catch (e) {
    say(`the server did not answer (${e.message})`, true);
    $("fit-status").hidden = true;
    return;
  }
  if (!response.ok) {
    say(await errorOf(response), true);
    $("fit-status").hidden = true;
    return;
  }
  const { id, job } = await response.json();
  state.job = job;
  follow(id, job);
}

function follow(id, job) {
  const events = new EventSource(`/api/jobs/${job}/events`);
  state.events = events;
  const update = (snap) => {
    $("progress").value = snap.progress;
    $("stage").textContent = snap.state === "running" ? `${snap.stage} ${Math.round(100 * snap.progress)} %`
      : snap.state;
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
      setModel(id);
      say("model ready: generate below");
      showSummary(id);
    } else if (snap.state === "cancelled") {
      say("fit cancelled");
    } else {
      say(snap.error || "the fit failed", true);
    }
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
  if (!response.ok) say(await errorOf(response), true);
}

function fitFile(file) {
  if (!file) return;
  $("builtin").value = "";
  setExemplar(URL.createObjectURL(file));
  const form = fitFields();
  form.append("image", file, file.name);
  startFit(form);
}

function fitBuiltin(name) {
  if (!name) return;
  setExemplar(`/api/builtins/${name}.png`);
  const form = fitFields();
  form.append("builtin", name);
  startFit(form);
}

async function uploadModel(file) {
  if (!file) return;
  stopEvents();
  $("fit-status").hidden = true;
  setExemplar(null);
  setModel(null);
  say(`uploading ${file.name}`);
  const response = await fetch("/api/models/upload", {
    method: "POST", body: file, headers: { "Content-Type": "application/octet-stream" },
  });
  if (!response.ok) { say(await errorOf(response), true); return; }
  const { id } = await response.json();
  setModel(id);
  say(`model ${file.name} loaded: generate below`);
  showSummary(id);
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
  return body;
}

async function generate(body) {
  const response = await fetch(`/api/models/${state.modelId}/images`, {
    method: "POST", body: JSON.stringify(body), headers: { "Content-Type": "application/json" },
  });
  if (!response.ok) throw new Error(await errorOf(response));
  return response.blob();
}

function showResult(url, seed, blob, what) {
  if (state.resultUrl) URL.revokeObjectURL(state.resultUrl);
  state.resultUrl = url;
  const img = $("result");
  img.onload = () => {
    $("result-caption").textContent = `${what || "result"}: ${img.naturalHeight}x${img.naturalWidth}, seed ${seed}`;
    drawTiled(img);
  };
  img.src = url;
  img.hidden = false;
  const link = $("download-png");
  link.href = url;
  link.setAttribute("download", what ? `tghop-${what}-seed${seed}.png` : `tghop-seed${seed}.png`);
  link.hidden = false;
  if (blob) setEditorPicture(blob, `tghop-seed${seed}.png`);
}

function drawTiled(img) {
  const canvas = $("tiled");
  const w = img.naturalWidth, h = img.naturalHeight;
  canvas.width = 3 * w;
  canvas.height = 3 * h;
  const ctx = canvas.getContext("2d");
  for (let y = 0; y < 3; y++) for (let x = 0; x < 3; x++) ctx.drawImage(img, x * w, y * h);
  canvas.dataset.ready = "1";
}

async function withBusy(button, work, report) {
  if (state.busy) return;
  state.busy = true;
  const old = button.textContent;
  button.textContent = "working...";
  updateButtons();
  try {
    await work();
  } catch (e) {
    (report || say)(e.message, true);
  } finally {
    button.textContent = old;
    state.busy = false;
    updateButtons();
  }
}

function onGenerate(event) {
  event.preventDefault();
  if (!state.modelId) return;
  withBusy($("go"), async () => {
    const seed = Number($("seed").value);
    say("generating");
    const blob = await generate(generation(seed));
    showResult(URL.createObjectURL(blob), seed, blob);
    say("");
  });
}

function onStrip() {
  if (!state.modelId) return;
  withBusy($("strip-go"), async () => {
    const strip = $("strip");
    for (const old of strip.querySelectorAll("img")) URL.revokeObjectURL(old.src);
    strip.textContent = "";
    const first = Number($("seed").value);
    const [h, w] = [Number($("height").value), Number($("width").value)];
    for (let i = 0; i < 8; i++) {
      const seed = first + i;
      say(`seed ${seed} (${i + 1} of 8)`);
      const url = URL.createObjectURL(await generate(generation(seed, [h, w])));
      const figure = document.createElement("figure");
      const img = document.createElement("img");
      img.src = url;
      img.alt = `seed ${seed}`;
      img.title = `seed ${seed}: click to pick`;
      img.dataset.seed = String(seed);
      img.addEventListener("click", async () => {
        for (const other of strip.querySelectorAll("img")) other.classList.remove("chosen");
        img.classList.add("chosen");
        $("seed").value = String(seed);
        const blob = await (await fetch(url)).blob();
        showResult(URL.createObjectURL(blob), seed, blob);
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
  if (inpaint && !editor.blob) sayInpaint("generate an image first, or use a picture of your own");
}

// The picture to paint on: the latest result, or a picture the user chose.
function setEditorPicture(blob, name) {
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
    clearMask();
    // Small pictures are shown larger (up to 3 times, at most 640 pixels wide) to paint on.
    $("editor").style.width = `${Math.max(w, Math.min(3 * w, 640))}px`;
    $("editor").hidden = false;
    $("editor").dataset.ready = "1";
  };
  img.onerror = () => sayInpaint(`the browser cannot show ${editor.name}; use a PNG or JPEG picture`, true);
  $("editor").dataset.ready = "";
  img.src = editor.url;
  updateButtons();
  sayInpaint("");
}

function clearMask() {
  const canvas = $("mask");
  canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height);
}

function brushPoint(event) {
  const canvas = $("mask");
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
function moveCursor(event) {
  const canvas = $("mask"), cursor = $("brush-cursor");
  const rect = canvas.getBoundingClientRect();
  const size = Number($("brush").value) * rect.width / canvas.width;
  cursor.style.width = cursor.style.height = `${size}px`;
  cursor.style.left = `${event.clientX - rect.left}px`;
  cursor.style.top = `${event.clientY - rect.top}px`;
  cursor.hidden = false;
}

function onBrushMove(event) {
  moveCursor(event);
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

function onFill() {
  if (!state.modelId || !editor.blob) return;
  withBusy($("fill"), async () => {
    const mask = await maskBlob();
    if (!mask) { sayInpaint("paint the hole first: drag the brush over the picture", true); return; }
    const seed = $("inpaint-seed").value.trim();
    const form = new FormData();
    form.append("image", editor.blob, editor.name);
    form.append("mask", mask, "mask.png");
    if (seed !== "") form.append("seed", seed);
    form.append("tile", $("inpaint-tile").checked ? "true" : "false");
    sayInpaint("filling");
    const response = await fetch(`/api/models/${state.modelId}/inpaint`, { method: "POST", body: form });
    if (!response.ok) throw new Error(await errorOf(response));
    const blob = await response.blob();
    const used = response.headers.get("X-Tghop-Seed");
    showResult(URL.createObjectURL(blob), used, blob, "inpainted");
    sayInpaint(`filled (seed ${used}): paint again to fill more, or download it`);
  }, sayInpaint);
}

function onPicture(file) {
  if (!file) return;
  setEditorPicture(file, file.name);
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
  $("cancel").addEventListener("click", cancelFit);
  $("gen-form").addEventListener("submit", onGenerate);
  $("strip-go").addEventListener("click", onStrip);
  for (const radio of document.querySelectorAll("input[name=mode]")) {
    radio.addEventListener("change", () => { if (radio.checked) setMode(radio.value); });
  }
  $("brush").addEventListener("input", () => { $("brush-size").textContent = `${$("brush").value} px`; });
  $("clear").addEventListener("click", clearMask);
  $("fill").addEventListener("click", onFill);
  $("picture").addEventListener("change", (e) => onPicture(e.target.files[0]));
  const mask = $("mask");
  mask.addEventListener("pointerdown", onBrushDown);
  mask.addEventListener("pointermove", onBrushMove);
  mask.addEventListener("pointerup", onBrushUp);
  mask.addEventListener("pointercancel", onBrushUp);
  mask.addEventListener("pointerleave", () => { $("brush-cursor").hidden = true; });
  $("zoom").addEventListener("change", (e) => document.body.classList.toggle("zoom", e.target.checked));
  const drop = $("drop");
  drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    const file = e.dataTransfer.files[0];
    if (!file) return;
    if (file.name.toLowerCase().endsWith(".npz")) uploadModel(file); else fitFile(file);
  });
  document.body.dataset.ready = "1";
}

document.addEventListener("DOMContentLoaded", init);
