// tghop serve's page, section 3: the last results kept side by side (Generate's, a seed picked from the strip,
// Paint's, Remix's, Morph's, a Fill or Extend, the co-occurrence model's), each with its settings; a click shows
// one again as the result (a plain result's settings back in Generate's fields), each downloadable. Bounded: the
// last HISTORY_MAX, and at most HISTORY_BYTES of their PNGs (a material's maps counted); each kept as its PNG
// and a thumbnail of at most HISTORY_THUMB px drawn once, not a full-size picture decoded in the page. Kept across a
// reload too (0.59): each entry's PNGs and settings in the browser's IndexedDB (this address's), the same bounds.
"use strict";

const HISTORY_MAX = 12;
const HISTORY_BYTES = 256 * 1024 * 1024;
const HISTORY_THUMB = 120;

// [{blob, maps, seed, what, name, pick, download, thumb, key}], the newest first (`key`: its record's in the store);
// `pick`: the strip run of a seed picked from it (a second pick from the same strip replaces the first: clicking
// through the 8 seeds keeps one).
const recent = { entries: [] };

// A result just shown (showResult) kept at the front of the history; one kept already (shown again: Undo, a pick
// from the history) stays where it is. `pick`: the strip run it was picked from, if it was. A plain result of the same
// model, settings and seed as an entry (Generate pressed again) takes that entry's place at the front (0.60; 0.59 kept
// both): whether it did.
function keepResult(blob, maps, seed, what, name, pick) {
  const kept = blob && recent.entries.find((e) => e.blob === blob);
  if (kept) keepShown(kept);
  if (!blob || kept) { renderHistory(); return false; }
  const same = sameAs(what, seed, name);
  const again = same === null ? -1 : recent.entries.findIndex((e) => sameAs(e.what, e.seed, e.name) === same);
  if (again >= 0) dropEntry(again);
  const front = recent.entries[0];
  if (pick && front && front.pick === pick) dropEntry(0);
  const entry = { blob, maps, seed, what, name, pick, download: URL.createObjectURL(blob), thumb: null, key: null };
  recent.entries.unshift(entry);
  storeEntry(entry);
  const bytes = (e) => (e.maps ? e.maps.reduce((sum, m) => sum + m.blob.size, 0) : e.blob.size);
  let total = recent.entries.reduce((sum, e) => sum + bytes(e), 0);
  while (recent.entries.length > 1 && (recent.entries.length > HISTORY_MAX || total > HISTORY_BYTES)) {
    total -= bytes(recent.entries[recent.entries.length - 1]);
    dropEntry(recent.entries.length - 1);
  }
  renderHistory();
  thumbnail(entry);
  return again >= 0;
}

// What makes a plain result (Generate's, a seed picked from the strip) the same as another: its model, its seed and
// every setting sent, which give the same bytes (docs/serve.md); null for the rest (a painted guide, a fill: what made
// them is not all in their settings).
function sameAs(what, seed, name) {
  if (what || !name || !name.model) return null;
  const { models, by, ...settings } = name;  // names, not settings
  return JSON.stringify([seed, Object.entries(settings).sort()]);
}

function dropEntry(i) {
  const [entry] = recent.entries.splice(i, 1);
  URL.revokeObjectURL(entry.download);
  if (entry.thumb) entry.thumb.close();
  entry.dropped = true;
  if (entry.key !== null) storeDo("readwrite", (store) => store.delete(entry.key));
}

// The browser's store of the recent results (IndexedDB "tghop", its object store "recent": one record an entry, its
// key growing with each) and of the working model ("page", its record "working"). Where the browser has none, or
// refuses it (a private window may), the page keeps them until it is left, as 0.58 did.
const HISTORY_DB = "tghop", HISTORY_STORE = "recent", PAGE_STORE = "page";
let historyDb = null;

function openHistoryDb() {
  return new Promise((resolve) => {
    let request;
    try {
      request = indexedDB.open(HISTORY_DB, 1);
    } catch (e) {
      resolve(null);
      return;
    }
    request.onupgradeneeded = () => {
      request.result.createObjectStore(HISTORY_STORE, { autoIncrement: true });
      request.result.createObjectStore(PAGE_STORE);
    };
    request.onsuccess = () => resolve(request.result);
    request.onerror = () => resolve(null);
    request.onblocked = () => resolve(null);
  });
}

// `work(store)` in a transaction of `mode` on `name` (the recent results'); its request's result (null when there is
// no store or it fails).
function storeDo(mode, work, name = HISTORY_STORE) {
  if (!historyDb) return Promise.resolve(null);
  return new Promise((resolve) => {
    try {
      const tx = historyDb.transaction(name, mode);
      const request = work(tx.objectStore(name));
      tx.oncomplete = () => resolve(request.result);
      tx.onerror = tx.onabort = () => resolve(null);
    } catch (e) {
      resolve(null);
    }
  });
}

// An entry kept in the store: its PNGs (a material's every map) and settings; not its strip run (this page's).
async function storeEntry(entry) {
  const maps = entry.maps ? entry.maps.map((m) => ({ name: m.name, suffix: m.suffix, depth: m.depth, blob: m.blob }))
    : null;
  const record = { blob: entry.blob, maps, seed: entry.seed, what: entry.what, name: entry.name };
  const key = await storeDo("readwrite", (store) => store.add(record));
  entry.key = key;
  if (entry.dropped && key !== null) storeDo("readwrite", (store) => store.delete(key));  // dropped meanwhile
  else if (state.lastShown && state.lastShown.blob === entry.blob) keepShown(entry);  // shown still: kept so
}

// Which entry is the result shown (its key, the page's record "shown"; null: none of them, a picture of one's own), so
// that a reload shows it again beside the exemplar (0.60; 0.59 left it in Recent results only, the result empty). An
// entry whose key has not come yet is kept by storeEntry.
function keepShown(entry) {
  if (entry && entry.key === null) return;
  const key = entry ? entry.key : null;
  storeDo("readwrite", (store) => store.put(key, "shown"), PAGE_STORE);
}

// The result shown before the reload shown again (as a click on its entry shows it, Generate's fields left as they were
// kept); with no record of it (a store of 0.59), the newest. Called once, when the page starts, after its working
// model: the caption says whether that model made it.
async function restoreShown() {
  const key = await storeDo("readonly", (store) => store.get("shown"), PAGE_STORE);
  if (state.resultUrl || !recent.entries.length) return;  // something shown meanwhile, or nothing kept
  const entry = key === undefined ? recent.entries[0] : recent.entries.find((e) => e.key === key);
  if (entry) showResult(URL.createObjectURL(entry.blob), entry.seed, entry.blob, entry.what, entry.maps, entry.name);
}

// The entries kept by the page before a reload, shown again (the newest first); the store's older records, beyond
// the bounds, removed. Called once, when the page starts.
async function restoreHistory() {
  historyDb = await openHistoryDb();
  const keys = await storeDo("readonly", (store) => store.getAllKeys());
  const records = await storeDo("readonly", (store) => store.getAll());
  if (!keys || !records) return;
  const restored = [];
  let total = 0;
  for (let i = records.length - 1; i >= 0; i--) {
    const r = records[i];
    const size = r.maps ? r.maps.reduce((sum, m) => sum + m.blob.size, 0) : r.blob.size;
    if (restored.length >= HISTORY_MAX || (restored.length && total + size > HISTORY_BYTES)) {
      storeDo("readwrite", (store) => store.delete(keys[i]));
      continue;
    }
    total += size;
    restored.push({ ...r, pick: null, download: URL.createObjectURL(r.blob), thumb: null, key: keys[i] });
  }
  recent.entries.push(...restored);  // after any made while the store opened (the newest)
  renderHistory();
  for (const entry of restored) thumbnail(entry);
}

// Every entry forgotten, here and in the store (the "Forget" button).
function forgetHistory() {
  while (recent.entries.length) dropEntry(0);
  storeDo("readwrite", (store) => store.clear());
  keepShown(null);
  renderHistory();
  keepFocus($("history-forget"), $("go"));
}

// The entry's thumbnail (an ImageBitmap of at most HISTORY_THUMB px a side), drawn into its canvas once made.
async function thumbnail(entry) {
  try {
    const full = await createImageBitmap(entry.blob);
    const scale = Math.min(1, HISTORY_THUMB / Math.max(full.width, full.height));
    const [w, h] = [Math.max(1, Math.round(full.width * scale)), Math.max(1, Math.round(full.height * scale))];
    full.close();
    entry.thumb = await createImageBitmap(entry.blob, { resizeWidth: w, resizeHeight: h, resizeQuality: "medium" });
  } catch (e) {
    return;  // not decodable here: the entry shows its caption only
  }
  if (recent.entries.includes(entry)) renderHistory(); else entry.thumb.close();
}

// An entry's settings in words: "result 256x256, seed 3, tileable, quality best (bricks)".
function settingsText(entry) {
  const name = entry.name || {}, parts = [];
  const size = name.size ? ` ${name.size[0]}x${name.size[1]}` : "";
  parts.push(`${entry.what || "result"}${size}`);
  if (entry.seed !== null && entry.seed !== undefined) parts.push(`seed ${entry.seed}`);
  if (name.fill) parts.push(`fill ${name.fill}`);  // a strip's fill k of the seed (tghop inpaint --count's)
  if (name.tile) parts.push("tileable");
  if (name.refine !== undefined) parts.push(`${name.refine} refinement rounds`);
  if (name.n_patches !== undefined) parts.push(`patch pool ${name.n_patches}`);
  if (name.paper) parts.push("the paper's pipeline");
  if (name.quality) parts.push(`quality ${name.quality}`);
  const models = name.of || (name.models || []).join(" + ");
  return parts.join(", ") + (models ? ` (${models})` : "");
}

// The history's row: one button per entry (its thumbnail and settings; the one shown marked), a download under it.
function renderHistory() {
  const row = $("history");
  row.textContent = "";
  $("history-box").hidden = !recent.entries.length;
  const shown = state.lastShown && state.lastShown.blob;
  recent.entries.forEach((entry, i) => {
    const figure = document.createElement("figure");
    const button = document.createElement("button");
    button.type = "button";
    button.className = "history-item";
    const text = settingsText(entry);
    button.setAttribute("aria-label", `${text}: show it again`);
    button.setAttribute("aria-pressed", String(entry.blob === shown));
    if (entry.thumb) {
      const canvas = document.createElement("canvas");
      canvas.width = entry.thumb.width;
      canvas.height = entry.thumb.height;
      canvas.getContext("2d").drawImage(entry.thumb, 0, 0);
      button.append(canvas);
    }
    button.addEventListener("click", () => showAgain(entry));
    const caption = document.createElement("figcaption");
    caption.textContent = text;
    const link = document.createElement("a");
    const base = resultBase(entry.seed, entry.what, fileName(entry.name));
    link.href = entry.download;
    link.textContent = entry.maps ? "Download (.zip)" : "Download";
    // A material's: every map, in one ZIP as Download all maps makes it (0.58 saved its albedo only)
    link.setAttribute("download", entry.maps ? `${base}.zip` : `${base}.png`);
    link.setAttribute("aria-label", `download ${text}${entry.maps ? ", every map (a ZIP)" : ""}`);
    if (entry.maps) {
      link.addEventListener("click", (e) => { e.preventDefault(); downloadZip(base, entry.maps); });
    }
    figure.append(button, caption, link);
    figure.dataset.index = String(i);
    row.append(figure);
  });
}

// resultBase's fields of an entry's name (a picture of the user's own, filled, has its models and size too).
function fileName(name) {
  return { models: (name && name.models) || ["result"], size: (name && name.size) || ["?", "?"],
    tile: Boolean(name && name.tile), fill: name && name.fill };
}

// An entry shown again as the result; a plain result's (Generate's, a seed's) settings put back in Generate's fields.
function showAgain(entry) {
  const { blob, maps, seed, what, name } = entry;
  showResult(URL.createObjectURL(blob), seed, blob, what, maps, name);
  if (what || !name || !name.size) return;
  [$("height").value, $("width").value] = name.size.map(String);
  $("seed").value = String(seed);
  $("tile").checked = Boolean(name.tile);
  $("refine").value = name.refine === undefined ? "" : String(name.refine);
  $("n_patches").value = name.n_patches === undefined ? "" : String(name.n_patches);
  $("paper-gen").checked = Boolean(name.paper);
  $("quality").value = name.quality || "default";
  keepFields();
  sayGenerate(`seed ${seed} shown again: its settings are back in the fields above`);
}

// The working model kept across a reload too (0.59: a reload left the page empty, the model still in the server's
// cache but to be fitted again): its id, name and kind, its exemplar (a built-in's name, or the file picked) and the
// maps it was fitted with; a model file's has no exemplar. Kept at each change of the working model (setWorking).
function keepWorking(working) {
  const record = working && working.modelId ? {
    modelId: working.modelId, name: working.name, material: working.material,
    builtin: (working.source && working.source.builtin) || null, file: (working.source && working.source.file) || null,
    maps: working.maps || [],
  } : null;
  storeDo("readwrite", (store) => (record ? store.put(record, "working") : store.delete("working")), PAGE_STORE);
}

// Generate's fields and the fit settings (their values, and whether the settings are open) kept across a reload too
// (0.59: they went back to their defaults while the model and the results came back, so that the next Generate made
// a 256x256 of seed 1 whatever the artist had set), in the page's store (record "fields"), at each change; and the
// modes' fields (0.60; 0.59 put them back to their defaults): Paint's, Morph's (not A and B: the page's models),
// Inpaint's and Extend's, Co-occurrence's, and the brushes' sizes. Not Inpaint's erase (a tool, as the mask is).
const KEPT_FIELDS = ["height", "width", "seed", "refine", "n_patches", "tile", "paper-gen", "quality",
  "layout", "paper-fit", "scale", "n_clusters", "n_codewords", "stride", "max_patches",
  "paint-brush", "transition", "paint-seed", "morph-height", "morph-width", "morph-seed",
  "brush", "inpaint-seed", "inpaint-count", "inpaint-tile", "extend-height", "extend-width", "extend-anchor",
  "cooc-length", "cooc-morph-seed", "cooc-height", "cooc-width", "cooc-brush", "cooc-boost-a", "cooc-boost-b",
  "cooc-boost-factor", "cooc-edit-seed"];
// `touched`: a field changed before the store answered (restoreFields), which it does not overwrite.
const keptFields = { restored: false, touched: false };

function keepFields() {
  if (!keptFields.restored) keptFields.touched = true;
  const record = { open: $("fit-settings").open };
  for (const id of KEPT_FIELDS) record[id] = $(id).type === "checkbox" ? $(id).checked : $(id).value;
  storeDo("readwrite", (store) => store.put(record, "fields"), PAGE_STORE);
}

// Each field's change kept (keepFields); a value the page sets itself (a recent result shown again, a seed picked)
// is kept by its setter.
function wireKeptFields() {
  for (const id of KEPT_FIELDS) {
    $(id).addEventListener("input", keepFields);
    $(id).addEventListener("change", keepFields);
  }
  $("fit-settings").addEventListener("toggle", keepFields);
}

// The fields of before the reload put back (each of the kind it is: a value a menu lacks is left). Called once, when
// the page starts, after the store has opened.
async function restoreFields() {
  const kept = await storeDo("readonly", (store) => store.get("fields"), PAGE_STORE);
  keptFields.restored = true;
  if (!kept || keptFields.touched) return;
  for (const id of KEPT_FIELDS) {
    const el = $(id), value = kept[id];
    if (el.type === "checkbox" && typeof value === "boolean") el.checked = value;
    else if (el.type !== "checkbox" && typeof value === "string" &&
             (el.tagName !== "SELECT" || [...el.options].some((o) => o.value === value))) el.value = value;
    if (el.type === "range") el.dispatchEvent(new Event("input"));  // its size said beside it ("24 px")
  }
  if (typeof kept.open === "boolean") $("fit-settings").open = kept.open;
}

// The working model of before the reload made the working one again, when the server still has it (its cache may
// have dropped it) and nothing was picked meanwhile; said. Called once, when the page starts.
async function restoreWorking() {
  const kept = await storeDo("readonly", (store) => store.get("working"), PAGE_STORE);
  if (!kept || state.source || state.modelId) return;
  const response = await fetch(`/api/models/${kept.modelId}`).catch(() => null);
  if (state.source || state.modelId || state.working) return;  // picked meanwhile
  if (!response || !response.ok) {
    if (response && response.status === 404) {
      say(`the model of ${kept.name} is no longer on the server (its cache dropped it): pick its exemplar again`);
    }
    return;
  }
  const source = kept.builtin ? { builtin: kept.builtin } : kept.file ? { file: kept.file } : null;
  const url = kept.builtin ? `/api/builtins/${kept.builtin}.png` : kept.file ? URL.createObjectURL(kept.file) : null;
  state.source = source;
  state.pendingName = kept.name;
  $("builtin").value = kept.builtin || "";
  setExemplar(url);
  listMaps(kept.maps || []);
  setWorking({ source, exemplarUrl: url, modelId: kept.modelId, material: kept.material, name: kept.name,
    maps: kept.maps || [] });
  setModel(kept.modelId, kept.material);
  say(`the model of ${kept.name} is back (kept across the reload): generate below`);
  // Generate brought into sight as after a fit (0.64: 0.63 left it below the fold at 1024x700, under the summary)
  showSummary(kept.modelId).then(() => generateInSight(kept.modelId));
}
