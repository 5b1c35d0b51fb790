// tghop serve's page, section 1 (Exemplar): the exemplar and its maps (a material) are fitted, the fit's
// progress followed and its model summarized; or a saved model file is loaded.
"use strict";

// The exemplar shown (null: none). A URL of the working model's (state.working) is kept for going back to it.
function setExemplar(url) {
  const old = state.exemplarUrl;
  if (old && old !== url && old.startsWith("blob:") && !(state.working && state.working.exemplarUrl === old)) {
    URL.revokeObjectURL(old);
  }
  state.exemplarUrl = url;
  const img = $("exemplar");
  img.classList.remove("enlarged");  // until the new picture's size is known (enlargeSmall)
  if (url) { img.src = url; img.hidden = false; } else { img.removeAttribute("src"); img.hidden = true; }
  exemplarCaption();
}

// An exemplar smaller than READABLE_SIDE on its longer side is shown enlarged by a whole factor (2 or more), its
// pixels kept square (pixelated); zoom 1:1 shows it at its size. (At its size a 64x64 exemplar was a thumbnail
// beside a 256x256 result.)
const READABLE_SIDE = 256;

function enlargeSmall(img) {
  const side = Math.max(img.naturalWidth, img.naturalHeight);
  const factor = side ? Math.floor(READABLE_SIDE / side) : 1;
  img.classList.toggle("enlarged", factor > 1);
  img.dataset.factor = String(Math.max(1, factor));
  img.style.setProperty("--enlarged-width", `${factor * img.naturalWidth}px`);
  exemplarCaption();
}

// "exemplar" under a picture (with its size and factor while it is shown enlarged); a model file's name where a loaded
// model has none; nothing under nothing.
function exemplarCaption() {
  const caption = $("exemplar-caption"), img = $("exemplar");
  const working = state.working;
  const file = !state.exemplarUrl && state.modelId && working && working.modelId === state.modelId;
  const enlarged = img.classList.contains("enlarged") && !document.body.classList.contains("zoom") ?
    ` (${img.naturalHeight}x${img.naturalWidth}, shown ${img.dataset.factor}\u00d7 larger)` : "";
  caption.textContent = state.exemplarUrl ? `exemplar${enlarged}`
    : file ? `${working.name} (a model file: no picture of its exemplar)` : "";
  caption.hidden = !caption.textContent;
  resultCaption();  // whether the result beside it is of its model
}

// The working model: {source, exemplarUrl, modelId, material, name, maps}, or null (none). A refused or cancelled
// fit and a refused model file go back to it (the page as it was before that pick); a fit that ends or a
// model file loaded replaces it.
function setWorking(working) {
  if (!working || $("strip").dataset.model !== working.modelId) clearStrip();  // an earlier model's seeds
  const old = state.working && state.working.exemplarUrl;
  state.working = working;
  keepWorking(working);  // across a reload too (history.js)
  if (old && old.startsWith("blob:") && old !== state.exemplarUrl && !(working && working.exemplarUrl === old)) {
    URL.revokeObjectURL(old);
  }
  exemplarCaption();
}

// A fit refused (before or after its job started) or cancelled, or a model file refused: the page goes back
// to the working model, its source and exemplar (the empty page when there is none), the maps to those
// before that pick (`undo.mapFiles`). `lead`: what happened, said first (an error unless `error` is false).
function backToWorking(lead, undo, error = true) {
  const working = state.working;
  keepFocus($("cancel"), $("drop"));
  $("fit-status").hidden = true;
  listMaps(undo.mapFiles, undo.held);
  state.source = working ? working.source : null;
  state.pendingName = working ? working.name : null;
  $("builtin").value = (working && working.source && working.source.builtin) || "";
  setExemplar(working ? working.exemplarUrl : null);
  // A material's patch statistics as its summary said them (null: not known yet): Generate stays on (0.60)
  setModel(working ? working.modelId : null, working ? working.material : false, working ? working.patches : null);
  const kept = working ? `the model of ${working.name} stays` : "no model yet";
  say(`${lead} (${undo.maps ? "the maps were not added" : `${undo.name} was not used`}; ${kept})`, error);
  if (working) showSummary(working.modelId);
}

// `material`: whether the model is a material, when known (a fit's: it sent maps); else null until
// its summary says (an uploaded file).
function setModel(id, material = null, patches = null) {
  state.modelId = id;
  setMaterial(material, patches);
  if (id) addSessionModel(id, state.pendingName);
  updateButtons();
  exemplarCaption();
  const [href, name] = id ? modelDownload(id, workingStem()) : [null, null];
  offerDownload($("download-model"), href, name);
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
  // What reading its file warned of (a newer tghop's file), when not said yet: a file kept by an earlier server (the
  // cache of another tghop, or a restart) is read anew, and its fit or upload said nothing of it (0.57)
  const notes = unsaid(s.notes || []);
  if (notes.length) say([$("message").textContent, ...notes].filter(Boolean).join(". "));
  // Its patch statistics (a texture model's own, 0.61; a material's albedo's): a server of 0.60 said a material's only
  const levels = "patch_levels" in s ? s.patch_levels : maps ? s.material.patch_levels : null;
  const patches = levels === null ? null : Boolean(levels);
  if (state.working && state.working.modelId === id) {
    state.working.material = Boolean(maps);
    state.working.patches = patches;
  }
  const listed = state.models.find((m) => m.id === id);
  if (listed && s.params) listed.patchSize = s.params.patch_size;  // Morph's least height (morphMinimum)
  setMaterial(Boolean(maps), patches);
}

// The quality preset applies where the model has patch statistics (`patches`: its summary's patch_levels above 0;
// false: fitted with the paper's settings or patch_levels 0, a texture model of tghop 0.14, a material of 0.58; null:
// not known yet): a texture model's own (0.61: 0.60 offered best to one fitted with the paper's settings, a 422), a
// material's albedo's (0.59). `on` null: not known yet (an uploaded file until its summary comes). Not known, the menu
// is off, and so are Generate and 8 seeds (updateButtons), as best would be a 422 for a model without them: a material
// fitted here too, until its summary comes (0.60; 0.59 turned the menu on at the fit's end, and best pressed before
// the summary came was a 422 for one fitted with patch_levels 0); a texture model fitted here is known at its fit's
// end (fitPatches).
function setMaterial(on, patches = null) {
  state.material = on;
  state.patches = on === null ? null : patches;
  const listed = state.models.find((m) => m.id === state.modelId);
  if (listed && on !== null) listed.material = on;  // Morph takes texture models only (morphProblem)
  if (listed && on !== null && patches !== null) listed.patches = patches;  // Paint's and Remix's quality
  const bare = on !== null && patches === false, unknown = on === null || (on === true && patches === null);
  // The fix in the page's words (0.60's "fit it again without them" read as without patch statistics, and
  // "patch_levels 0" is no field of the page)
  const why = on ? "this material's albedo has no patch statistics (fitted by tghop 0.58, or with the paper's settings)"
    : "this model has no patch statistics (fitted with the paper's settings, or by tghop fit --patch-levels 0)";
  const fix = "fit it again with the paper's settings off (Fit settings)";
  $("quality").disabled = unknown || bare;
  $("quality").title = bare ? `${why}: ${fix}`
    : on === null ? "off until the page knows whether the model is a material (its summary)"
    : unknown ? "off until the page knows whether this material's albedo has patch statistics (its summary)" : "";
  // Why it is off, in its help too (which a screen reader reads with it): a title is a mouse's only, and a control
  // turned off is not reached with Tab. Shown for a material without statistics; for the moments of a fit or an
  // upload, to a screen reader only (shown, the help grew a line and shrank back with each fit).
  const off = $("quality-off");
  off.textContent = bare ? `Off now: ${why}; ${fix} for quality best.`
    : on === null ? "Off until the page knows whether the model is a material (its summary)."
    : unknown ? "Off until the page knows whether this material's albedo has patch statistics (its summary)." : "";
  off.hidden = !bare && !unknown;
  off.classList.toggle("to-screen-readers", unknown);
  updateButtons();
  if (!$("inpaint").hidden) inpaintHint();  // Fill and Extend may have changed
  if (!$("morph").hidden && state.models.length > 1) morphPicked();  // so may Morph
  if (!$("paint").hidden) paintPicked();  // and Paint
}

function fitFields() {
  const form = new FormData();
  if (!$("layout").checked) form.append("layout_factor", "none");
  if ($("paper-fit").checked) form.append("paper", "true");
  for (const name of ["scale", "n_clusters", "n_codewords", "stride", "max_patches"]) {
    const value = $(name).value.trim();
    if (value) form.append(name, value);
  }
  for (const file of sentMaps()) form.append(`map:${mapName(file.name)}`, file, file.name);
  return form;
}

// Whether a texture model fitted with `form` has patch statistics: not with the paper's settings (their patch_levels
// 0) nor patch_levels 0 (the API's field, which the page has not).
function fitPatches(form) {
  return form.get("paper") !== "true" && form.get("patch_levels") !== "0";
}

// The maps a fit now sends: those listed, but not while they wait for their albedo (an exemplar of their size).
function sentMaps() {
  return state.mapsHeld ? [] : state.mapFiles;
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

// The map files chosen (none: a texture model); the exemplar fitted last (the working one, or the one being
// fitted) is fitted again with them. Refused, the maps chosen before stay. With no exemplar they wait for it, and
// so do maps of another size than the last exemplar's (their albedo still to come: the order of adding does not
// matter); "No maps" then drops them, the working model kept.
async function setMapFiles(files) {
  const undo = { mapFiles: state.mapFiles, held: heldNow(), maps: true };
  if (!useMapFiles(files)) return;
  const browsed = withdrawBuiltin();  // browsed to by keyboard, waiting: the exemplar these maps go with
  const source = state.source, chosen = state.mapFiles;
  if (browsed && chosen.length) {  // compared with it first, as with a source (0.58 sent them unchecked)
    state.mapsChecking = chosen;  // a pick meanwhile takes them (clearOthersMaps), and compares them itself
    const other = await otherSize(chosen, `/api/builtins/${browsed}.png`);
    if (state.browsed && state.mapsChecking === chosen) return;  // browsed on meanwhile: the one settled on takes them
    if (state.mapsChecking === chosen) state.mapsChecking = null;
    if (state.source !== source || state.mapFiles !== chosen) return;  // another pick or maps meanwhile
    if (other) {  // they wait for their albedo, and the built-in is fitted without them, said (fitSource)
      listMaps(chosen, { source: { builtin: browsed }, other });
      fitBuiltin(browsed);
      return;
    }
  }
  if (!browsed && source && !chosen.length && undo.held) {
    const kept = state.working ? ` (the model of ${state.working.name} stays)` : "";
    say(`maps dropped: they were waiting for the next exemplar${kept}`);
    return;
  }
  if (!browsed && source && chosen.length) {
    state.mapsChecking = chosen;  // an exemplar picked meanwhile takes them (clearOthersMaps)
    const other = await otherSize(chosen, state.exemplarUrl);
    if (state.mapsChecking === chosen) state.mapsChecking = null;
    if (state.source !== source || state.mapFiles !== chosen) return;  // another pick or maps meanwhile
    if (other) { holdMaps(other, source); return; }
    const named = namedForAnother(chosen, source);
    if (named) { holdNamed(named, source); return; }
  }
  if (browsed) fitBuiltin(browsed, undo);
  else if (source && source.file) fitFile(source.file, undo);
  else if (source && source.builtin) fitBuiltin(source.builtin, undo);
  else if (chosen.length) say("pick or drop the albedo (exemplar) now: it is fitted with these maps");
  if (!browsed && source && chosen.length) {  // what the page took them for, said (another pick offers them to it)
    const whose = source.builtin ? `builtin:${source.builtin}` : source.file.name;
    say(`fitting ${whose} with ${chosen.map((f) => mapName(f.name)).join(", ")}, maps of its size; if they are ` +
      "another picture's, pick that picture: the maps are then one click from it");
  }
}

// The height and width of an image (a File, or a URL) as the browser reads it, or null when it cannot.
async function imageSize(image) {
  try {
    if (typeof image !== "string") {
      const bitmap = await createImageBitmap(image);
      const size = [bitmap.height, bitmap.width];
      bitmap.close();
      return size;
    }
    const img = new Image();
    img.src = image;
    await img.decode();
    return [img.naturalHeight, img.naturalWidth];
  } catch (e) {
    return null;  // not known here: the server checks it
  }
}

// The first map file whose size is not the exemplar's at `url` ({name, size, exemplar}), or null (all of its
// size, or a size the browser cannot read: the server says).
async function otherSize(files, url) {
  const exemplar = url ? await imageSize(url) : null;
  if (!exemplar) return null;
  for (const file of files) {
    const size = await imageSize(file);
    if (size && (size[0] !== exemplar[0] || size[1] !== exemplar[1])) {
      return { name: mapName(file.name), size, exemplar };
    }
  }
  return null;
}

// Maps of another size than the last exemplar's (`other`: otherSize's) are not its: they wait for the next
// exemplar picked or dropped (their albedo), the working model kept.
function holdMaps(other, source) {
  listMaps(state.mapFiles, { source, other });
  const kept = state.working ? `; the model of ${state.working.name} stays` : "";
  say(`${heldWhy()}; pick or drop it now (it is fitted with them${kept})`);
}

// The words a material's map files end in (tghop.map_names.MAP_KINDS but the albedo's), and the albedo's.
const MAP_WORDS = new Set(["normal", "normalgl", "normaldx", "nrm", "nrml", "nor", "norm", "n", "roughness", "rough",
  "rgh", "height", "displacement", "disp", "bump", "ao", "occlusion", "ambientocclusion", "metallic", "metalness",
  "metal", "specular", "spec", "glossiness", "gloss", "opacity", "emission", "emissive", "orm", "arm", "rma", "mra"]);
const ALBEDO_WORDS = new Set(["albedo", "basecolor", "basecolour", "diffuse", "diff", "color", "colour", "col", "bc"]);

// The picture a file's name says it is of: its stem's words before the last (a trailing resolution, 2k or 1024,
// and a normal map's convention, gl or dx, passed over) when the last is one of `kinds`, as one lower-case word
// ("Rock023_2K_NormalGL.png": "rock0232k"); "" when the name says no picture ("normal.png", or "scan.png" where a
// kind word is `needed`). An exemplar's name without an albedo word is its picture whole ("wall.jpg": "wall").
function pictureOf(filename, kinds, needed) {
  const words = filename.replace(/\.[^.]*$/, "").toLowerCase().split(/[^a-z0-9]+/).filter(Boolean);
  while (words.length > 1 && /^\d+k?$/.test(words[words.length - 1])) words.pop();
  while (words.length > 1 && /^(gl|ogl|opengl|dx|directx)$/.test(words[words.length - 1])) words.pop();
  if (words.length > 1 && kinds.has(words[words.length - 1])) words.pop();
  else if (needed) return "";
  return words.join("");
}

// The first map file named for another picture than the exemplar `source` ("rock_normal.png" with builtin:bricks
// or wall.jpg), or null: every map's name names one picture (a kind word after it) and the exemplar's another, neither
// holding the other. Maps named by their kind alone ("normal.png") are the exemplar's, as their size says.
function namedForAnother(files, source) {
  const pictures = new Set(files.map((f) => pictureOf(f.name, MAP_WORDS, true)));
  const [picture] = pictures;
  const exemplar = source.builtin || pictureOf(source.file.name, ALBEDO_WORDS, false);
  if (pictures.size !== 1 || !picture || !exemplar || picture.includes(exemplar) || exemplar.includes(picture)) {
    return null;
  }
  return files[0];
}

// Maps named for another picture than the last exemplar's (namedForAnother's `file`) wait for the next exemplar
// picked or dropped, as maps of another size do; the same exemplar picked again takes them (its name is no proof),
// and so does "Use them with ..." (offerMaps: a name is a guess, which one click undoes).
function holdNamed(file, source) {
  listMaps(state.mapFiles, true);
  const whose = source.builtin ? `builtin:${source.builtin}` : source.file.name;
  offerMaps(state.mapFiles, whose);
  say(`${file.name} is named for another picture than ${whose}: the maps wait for their albedo; pick or drop it ` +
      `now (it is fitted with them), or press "Use them with ${whose}" if they are its maps`);
}

// The choice the page made for maps of the exemplar's size, from their names or the order of the clicks, undone in
// one click (0.59): "Use them with NAME" refits the exemplar shown (`whose`) with `files`. Any other change of the
// maps (listMaps) takes the offer back.
function offerMaps(files, whose) {
  state.mapsOffer = files;
  $("maps-use").textContent = `Use them with ${whose}`;
  $("maps-use").hidden = false;
}

// "Use them with ...", pressed: the maps offered are the exemplar's, fitted with it (the one being fitted or the
// working one); refused or cancelled, the maps before come back (backToWorking).
function useOfferedMaps() {
  const files = state.mapsOffer, source = state.source;
  if (!files || !source) return;
  const undo = { mapFiles: state.mapFiles, held: heldNow(), maps: true };
  listMaps(files);
  keepFocus($("maps-use"), $("maps"));
  if (source.file) fitFile(source.file, undo); else fitBuiltin(source.builtin, undo);
}

// Why the maps listed wait (state.heldOff): "rock_normal is 128x160, not the 256x256 of builtin:bricks: ...".
function heldWhy() {
  const { source, other } = state.heldOff;
  const whose = source.builtin ? `builtin:${source.builtin}` : source.file.name;
  return `${other.name} is ${other.size.join("x")}, not the ${other.exemplar.join("x")} of ${whose}: the maps ` +
    "wait for their albedo";
}

// Whether the maps wait (listMaps's `held`: why, where it is known), for a pick's way back (backToWorking).
function heldNow() {
  return state.mapsHeld ? state.heldOff || true : false;
}

// The map files to fit with the next exemplar, listed; false (said, the maps chosen before kept) when
// their names clash.
function useMapFiles(files) {
  files = [...files];  // before the input is emptied: its FileList is live
  const problem = mapsProblem(files);
  $("maps").value = "";  // choosing the same files again is a change
  if (problem) { say(problem, true); return false; }
  listMaps(files);
  return true;
}

// `held`: the maps wait for the next exemplar (state.mapsHeld), and the list says so; an object: they are not of
// that exemplar (state.heldOff, holdMaps).
function listMaps(files, held = false) {
  state.mapsOffer = null;  // a choice of the page's, undone by "Use them with ..." (offerMaps): taken back
  if (document.activeElement === $("maps-use")) $("maps").focus();
  $("maps-use").hidden = true;
  state.mapFiles = files;
  state.mapsHeld = Boolean(held && files.length);
  state.heldOff = state.mapsHeld && typeof held === "object" ? held : null;
  const names = files.map((f) => mapName(f.name));
  $("maps-list").textContent = !names.length ? ""
    : `maps${state.mapsHeld ? " for the next exemplar" : ""}: ${names.join(", ")}`;
  if (!names.length) keepFocus($("maps-clear"), $("maps"));  // No maps, pressed: the focus goes to Add maps
  $("maps-clear").hidden = !names.length;
  return files;
}

// Another exemplar picked or a model file loaded (`source` null) than the one the maps listed go with
// (state.source, the last exemplar: the working one or the one being fitted): they are that material's, not
// the new one's, and are cleared, the list saying so (`whose`: whose maps they are not). A refused or cancelled
// pick lists them again (backToWorking). Maps listed with no exemplar yet wait for the one picked; the same
// exemplar picked again is fitted with them. The maps the new exemplar takes unchecked, which fitSource compares
// with its size, or null.
function clearOthersMaps(source, whose) {
  const old = state.source, files = state.mapFiles;
  // The exemplar whose size they are not, picked again: fitted without them, the maps waiting on (0.57 sent them,
  // to be refused for their size)
  if (state.mapsHeld && source && state.heldOff && sameSource(state.heldOff.source, source)) return null;
  if (state.mapsHeld && source) { listMaps(files); return files; }  // waiting for this exemplar: now its maps
  if (source && files.length && state.mapsChecking === files) return files;  // added as it was picked: its maps
  if (source && files.length && !old) return files;  // added before any exemplar: this one's
  if (!files.length || !old || state.mapsHeld || (source && sameSource(old, source))) return null;
  const cleared = listMaps([]);
  $("maps-list").textContent = `maps cleared: ${files.map((f) => mapName(f.name)).join(", ")} went with ` +
    `${old.builtin ? `builtin:${old.builtin}` : old.file.name}, not ${whose}`;
  if (source) offerIfSized(files, source, cleared);
  return null;
}

// Maps cleared by the pick of `source` offered to it (offerMaps) when they are of its size: the page took them for
// the last exemplar's, from the order of the clicks; maps added for the picture picked next are one click from it.
async function offerIfSized(files, source, cleared) {
  const exemplar = await imageSize(source.builtin ? `/api/builtins/${source.builtin}.png` : source.file);
  for (const file of files) {
    const size = exemplar && await imageSize(file);
    if (!size || size[0] !== exemplar[0] || size[1] !== exemplar[1]) return;
  }
  if (state.mapFiles !== cleared || !state.source || !sameSource(state.source, source)) return;
  offerMaps(files, source.builtin ? `builtin:${source.builtin}` : source.file.name);
}

// Whether two exemplars are the same: a built-in's name, or a file's name, size and date.
function sameSource(a, b) {
  if (a.builtin || b.builtin) return a.builtin === b.builtin;
  return a.file.name === b.file.name && a.file.size === b.file.size && a.file.lastModified === b.file.lastModified;
}

// A name that says albedo (albedo, diff, diffuse, color, colour, basecolor, as a word of the file's name).
const ALBEDO_NAME = /(^|[^a-z])(albedo|diff|diffuse|(base)?colou?r)([^a-z]|$)/i;

// Several files dropped at once are a material: the exemplar (its albedo) is the one named like an
// albedo when exactly one is, else the first; the others are its maps. A model file goes on its own. A map of another
// size than the albedo's (as the browser reads them) refuses the drop, said, nothing used (0.58 sent them, and the
// server refused the fit naming the sizes).
async function dropFiles(files) {
  const model = files.find((f) => /\.(npz|pt)$/i.test(f.name));
  if (model) {
    say(`${files.length} files dropped: drop the model file ${model.name} on its own (nothing was used)`, true);
    return;
  }
  const named = files.filter((f) => ALBEDO_NAME.test(f.name.replace(/\.[^.]*$/, "")));
  const albedo = named.length === 1 ? named[0] : files[0];
  const maps = files.filter((f) => f !== albedo);
  const request = state.fitRequest, source = state.source;
  const other = await otherSize(maps, albedo);
  if (request !== state.fitRequest || source !== state.source) return;  // another pick meanwhile
  if (other) {
    const sizes = `${other.size.join("x")}, not the ${other.exemplar.join("x")} of ${albedo.name}`;
    say(`${files.length} files dropped: ${other.name} is ${sizes}, the albedo; a material's maps are of its albedo's ` +
        "size (nothing was used)", true);
    return;
  }
  const undo = { mapFiles: state.mapFiles, held: heldNow(), name: albedo.name };
  if (!useMapFiles(maps)) return;
  fitFile(albedo, undo);
  say(`${files.length} files dropped: ${albedo.name} is the exemplar (the albedo), the others its maps ` +
      `(${maps.map((f) => mapName(f.name)).join(", ")}); "Add maps..." changes them`);
}

function stopEvents() {
  if (state.events) { state.events.close(); state.events = null; }
}

// A fit still running when another exemplar or a model file replaces it, or when the page is left (a reload),
// is cancelled: the page forgets it (keepalive: the request outlives the page). Whether there was one.
function dropRunningFit() {
  withdrawBuiltin();  // a built-in browsed to by keyboard, still waiting: replaced too
  stopEvents();
  const running = Boolean(state.job && !$("fit-status").hidden && !$("fit-status").dataset.state);
  if (running) fetch(`/api/jobs/${state.job}`, { method: "DELETE", keepalive: true }).catch(() => {});
  state.job = null;
  return running;
}

// The page left (a reload, another address): its running fit is withdrawn, as its generations are stopped;
// the page shown again from the browser's cache goes back to its working model.
function onPageHide() {
  if (dropRunningFit()) {
    state.fitRequest++;
    $("fit-status").dataset.state = "cancelled";
    backToWorking("fit cancelled when the page was left", state.fitUndo, false);
  }
}

// The fit's bar, its Cancel and the message under them brought into sight where they are out of it (0.63: at 400x800
// with the fit settings open they came below the fold, and a pick seemed to do nothing).
function fitInSight() {
  const status = $("fit-status"), message = $("message");
  const top = (status.hidden ? message : status).getBoundingClientRect().top;
  const below = message.getBoundingClientRect().bottom > window.innerHeight;
  if (top < 0 || below) message.scrollIntoView({ block: "nearest" });
}

// Generate brought into sight once "model ready: generate below" is said and the model's summary shown (0.63: at
// 1024x700 the summary pushed it below the fold), with the message where both fit in the window, else Generate alone.
function generateInSight(id) {
  if (state.modelId !== id) return;  // another model asked for meanwhile
  const go = $("go").getBoundingClientRect(), said = $("message").getBoundingClientRect();
  if (go.bottom <= window.innerHeight) return;  // in sight, or above it (the artist scrolled on)
  const room = window.innerHeight - go.bottom + said.top - 8;  // what of the window is left with both in it
  window.scrollBy(0, go.bottom - window.innerHeight + (room >= 0 ? Math.min(8, room) : 8));
}

// `undo`: how to go back when the fit is refused or cancelled (backToWorking); `note`: said with "model ready".
async function startFit(form, undo, note = "") {
  dropRunningFit();
  const attempt = { source: state.source, exemplarUrl: state.exemplarUrl, name: state.pendingName, maps: sentMaps() };
  const request = ++state.fitRequest;  // a later fit or upload, or a Cancel, meanwhile replaces this one
  state.fitUndo = undo;  // for a Cancel (cancelFit)
  setModel(null);
  $("summary").hidden = true;
  $("fit-status").hidden = false;
  delete $("fit-status").dataset.state;  // set again when this fit ends
  $("progress").value = 0;
  showStage($("progress"), $("stage"), "sending");
  fitInSight();
  $("cancel").disabled = false;
  say("");
  let response;
  try {
    response = await fetch("/api/models", { method: "POST", body: form });
  } catch (e) {
    if (request !== state.fitRequest) return;
    backToWorking(noAnswer(e), undo);
    return;
  }
  if (!response.ok) {
    const error = await errorOf(response);
    if (request !== state.fitRequest) return;
    backToWorking(error, undo);
    return;
  }
  const { id, job, notes } = await response.json();
  const material = [...form.keys()].some((k) => k.startsWith("map:"));  // a fit with maps makes a material
  attempt.patches = material ? null : fitPatches(form);  // a material's: its summary says (setMaterial)
  if (request !== state.fitRequest) {  // replaced or cancelled while its answer came: withdrawn, as dropRunningFit does
    fetch(`/api/jobs/${job}`, { method: "DELETE" }).catch(() => {});
    return;
  }
  state.job = job;
  $("fit-status").dataset.job = job;  // for scripts and tests: GET /api/jobs/{job}
  follow(id, job, material, attempt, undo, [note, ...(notes || [])].filter(Boolean));
}

// `notes`: what the server said of the upload (a transparent part learnt as texture, a colour profile converted,
// the first frame read, 16 bits made 8), told with "model ready".
function follow(id, job, material, attempt, undo, notes) {
  const events = new EventSource(`/api/jobs/${job}/events`);
  state.events = events;
  const update = (snap) => {
    $("progress").value = snap.progress;
    showStage($("progress"), $("stage"), snap.state !== "running" ? snap.state : $("cancel").disabled ? "cancelling"
      : snap.stage ? `${snap.stage} ${Math.round(100 * snap.progress)} %` : "starting");
  };
  events.addEventListener("progress", (e) => update(JSON.parse(e.data)));
  events.addEventListener("end", (e) => {
    const snap = JSON.parse(e.data);
    const focused = document.activeElement === $("cancel");  // turned off now: the focus goes on (below)
    stopEvents();
    update(snap);
    $("cancel").disabled = true;
    $("fit-status").dataset.state = snap.state;
    if (snap.state === "done") {
      $("progress").value = 1;
      setWorking({ ...attempt, modelId: id, material });
      setModel(id, material, attempt.patches);
      say(["model ready: generate below", ...notes].join(". "));
      const summary = showSummary(id);
      summary.then(() => generateInSight(id));
      // A material's Generate waits for its summary (setMaterial): the focus goes on to it then
      if (focused && $("go").disabled) {
        summary.then(() => { if (document.activeElement === $("drop")) $("go").focus(); });
      }
    } else if (snap.state === "cancelled") {
      backToWorking("fit cancelled", undo, false);
    } else {
      backToWorking(snap.error || "the fit failed", undo);
    }
    if (focused) (snap.state === "done" && !$("go").disabled ? $("go") : $("drop")).focus();  // next: Generate
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
  keepFocus($("cancel"), $("drop"));  // pressed: turned off, the focus back at the start, to pick another
  $("cancel").disabled = true;  // and the stage says so until the fit stops (follow)
  showStage($("progress"), $("stage"), "cancelling");
  if (!state.job) {  // its request still on its way (an exemplar sending): withdrawn, startFit cancels its job
    state.fitRequest++;
    $("fit-status").dataset.state = "cancelled";
    backToWorking("fit cancelled", state.fitUndo, false);
    return;
  }
  const response = await fetch(`/api/jobs/${state.job}`, { method: "DELETE" });
  if (!response.ok) { say(await errorOf(response), true); return; }
  if ((await response.json()).askers > 0) {  // another page asked for the same model: it fits on for that page
    stopEvents();
    $("fit-status").dataset.state = "cancelled";
    showStage($("progress"), $("stage"), "cancelled");
    backToWorking("fit cancelled here, going on for another page that asked for the same model", state.fitUndo,
      false);
  }
}

// `undo` given: a refit with other maps (setMapFiles) or a material dropped (dropFiles); else a pick.
function fitFile(file, undo) {
  if (!file) return;
  $("builtin").value = "";
  fitSource({ file }, URL.createObjectURL(file), file.name, undo, (form) => form.append("image", file, file.name));
}

function fitBuiltin(name, undo) {
  if (!name) return;
  const append = (form) => form.append("builtin", name);
  fitSource({ builtin: name }, `/api/builtins/${name}.png`, `builtin:${name}`, undo, append);
}

// The exemplar `source` (shown from `url`, named `label`) fitted, `append` adding it to the fit's fields. A pick
// (`undo` not given) that takes maps whose size was not compared with it (maps waiting for their albedo, or being
// read: clearOthersMaps) compares them first (a few milliseconds): of another size, they are no maps of it and are
// dropped, the page saying so, and it is fitted as a texture model (0.58 sent them, and the server refused the fit,
// naming the sizes).
async function fitSource(source, url, label, undo, append) {
  let taken = null;
  if (!undo) {
    undo = { mapFiles: state.mapFiles, held: heldNow(), name: label };
    taken = clearOthersMaps(source, "this exemplar's");
  }
  state.source = source;
  setExemplar(url);
  let dropped = null;
  if (taken) {
    dropped = await otherSize(taken, url);
    if (state.source !== source || state.mapFiles !== taken) return;  // another pick, or other maps, meanwhile
    if (dropped) dropMaps(dropped, label);
  }
  state.pendingName = label + (sentMaps().length ? ` + ${sentMaps().length} maps` : "");
  const form = fitFields();
  append(form);
  // What became of the maps, said while it fits and again with "model ready"
  const note = dropped ? `maps dropped: ${dropped.name} is ${dropped.size.join("x")}, not the ` +
    `${dropped.exemplar.join("x")} of ${label}, so they are not its maps; ${label} is fitted as a texture model (add ` +
    "its own maps to make a material, or pick their albedo and add them again)"
    : state.mapsHeld && state.heldOff ? `${heldWhy()} (this fit is without them)` : "";
  startFit(form, undo, note);
  if (note) say(note);
}

// Maps of another size than the exemplar just picked (`other`: otherSize's), which it took: dropped, the list saying
// so until maps are added again.
function dropMaps(other, label) {
  const names = state.mapFiles.map((f) => mapName(f.name)).join(", ");
  listMaps([]);
  $("maps-list").textContent = `maps dropped: ${names} (${other.size.join("x")}) are not of the ` +
    `${other.exemplar.join("x")} of ${label}`;
}

// Browsing the closed built-in menu by keyboard (app.js, wireBuiltinMenu: a change per option passed) fits the
// option it settles on, BROWSE_SETTLE_MS after the last change, or at once on Enter or when the menu is left;
// each change withdraws the fit still waiting, and so does any fit or model file asked for meanwhile. Settling
// back on the exemplar already fitted (or being fitted) fits nothing. A click's pick is fitted at once.
const BROWSE_SETTLE_MS = 700;

function fitBuiltinSoon(name) {
  withdrawBuiltin();
  if (state.source && state.source.builtin === name) return;
  state.browsed = { name, timer: setTimeout(settleBuiltin, BROWSE_SETTLE_MS) };
}

// The built-in waiting to be fitted, no longer waiting (null: none was).
function withdrawBuiltin() {
  const browsed = state.browsed;
  state.browsed = null;
  if (browsed) clearTimeout(browsed.timer);
  return browsed ? browsed.name : null;
}

function settleBuiltin() {
  const name = withdrawBuiltin();
  if (name) fitBuiltin(name);
}

// A model file refused goes back to the working model, as a refused exemplar does (backToWorking).
async function uploadModel(file) {
  if (!file) return;
  dropRunningFit();
  const request = ++state.fitRequest;  // a fit whose answer is still on its way is replaced; so is this upload
  const undo = { mapFiles: state.mapFiles, held: heldNow(), name: file.name };
  clearOthersMaps(null, "the model file's");
  state.source = null;
  $("builtin").value = "";  // the menu shows the working model's exemplar: none (0.62 kept the built-in before)
  $("fit-status").hidden = true;
  $("summary").hidden = true;  // the model it replaces: not what is loaded, whatever the answer
  setExemplar(null);
  setModel(null);
  say(`uploading ${file.name}`);
  fitInSight();
  let response;
  try {
    // the field `model` with the file's name, so that the server's messages name it (0.61 sent the bare body:
    // "the upload", and a refit's command "-o MODEL.npz")
    const form = new FormData();
    form.append("model", file);
    response = await fetch("/api/models/upload", { method: "POST", body: form });
  } catch (e) {
    if (request === state.fitRequest) backToWorking(noAnswer(e), undo);
    return;
  }
  if (!response.ok) {
    const error = await errorOf(response);
    if (request === state.fitRequest) backToWorking(error, undo);
    return;
  }
  const { id, notes } = await response.json();
  if (request !== state.fitRequest) return;  // another exemplar or model file asked for meanwhile
  state.pendingName = file.name;
  setWorking({ source: null, exemplarUrl: null, modelId: id, material: null, name: file.name });
  setModel(id);
  // `notes`: what the server said of the file (a model of a 16-bit exemplar, whose images here are 8-bit).
  say([`model ${file.name} loaded: generate below`, ...(notes || [])].join(". "));
  unsaid(notes || []);  // said here: not again with its summary or its images
  await showSummary(id);
  if (state.modelId === id && state.material) say(`material ${file.name} loaded: generate below (every map)`);
  generateInSight(id);
}
