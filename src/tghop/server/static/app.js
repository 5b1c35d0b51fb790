// tghop serve's page: the HTTP API under /api (docs/serve.md), nothing else.
"use strict";

const $ = (id) => document.getElementById(id);
const state = { modelId: null, job: null, events: null, resultUrl: null, exemplarUrl: null, busy: false };

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

function setModel(id) {
  state.modelId = id;
  $("go").disabled = !id;
  $("strip-go").disabled = !id;
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
  return URL.createObjectURL(await response.blob());
}

function showResult(url, seed) {
  if (state.resultUrl) URL.revokeObjectURL(state.resultUrl);
  state.resultUrl = url;
  const img = $("result");
  img.onload = () => {
    $("result-caption").textContent = `result: ${img.naturalHeight}x${img.naturalWidth}, seed ${seed}`;
    drawTiled(img);
  };
  img.src = url;
  img.hidden = false;
  const link = $("download-png");
  link.href = url;
  link.setAttribute("download", `tghop-seed${seed}.png`);
  link.hidden = false;
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

async function withBusy(button, work) {
  if (state.busy) return;
  state.busy = true;
  const old = button.textContent;
  button.textContent = "working...";
  $("go").disabled = $("strip-go").disabled = true;
  try {
    await work();
  } catch (e) {
    say(e.message, true);
  } finally {
    button.textContent = old;
    state.busy = false;
    $("go").disabled = $("strip-go").disabled = !state.modelId;
  }
}

function onGenerate(event) {
  event.preventDefault();
  if (!state.modelId) return;
  withBusy($("go"), async () => {
    const seed = Number($("seed").value);
    say("generating");
    showResult(await generate(generation(seed)), seed);
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
      const url = await generate(generation(seed, [h, w]));
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
        showResult(URL.createObjectURL(await (await fetch(url)).blob()), seed);
      });
      const caption = document.createElement("figcaption");
      caption.textContent = `seed ${seed}`;
      figure.append(img, caption);
      strip.append(figure);
    }
    say("click a seed to pick it");
  });
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
