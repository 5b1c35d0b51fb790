// tghop serve's page: the HTTP API under /api (docs/serve.md), nothing else. Plain scripts (no build
// step) that share the page's global scope, loaded by index.html in this order (deferred: each runs
// whole, in order, before DOMContentLoaded):
//   common.js    the page's state (state, editor) and what every part uses: $, say and sayIn (a status line,
//                an error an alert), keepFocus, showStage (a progress bar's label, its value told), errorOf,
//                updateButtons, withBusy and busyFetch (Stop), answeredFetch and noAnswer (a server that does not
//                answer), withProgress (a generation's bar), answerOf and postImage (the API's answers), withWarning
//                (a result's status with the server's warning), undoneLine (what an Undo says)
//   download.js  download links; a material's maps as one ZIP
//   fit.js       1. Exemplar: the fit of an exemplar and its maps, its progress; a model file
//   generate.js  2. Generate and 3. Result: generating, the strip of seeds, the result and its tiling
//   history.js   the recent results side by side (each shown again with a click, downloadable), bounded
//   inpaint.js   Inpaint mode: the mask brush (or a mask from a file), Fill and Extend
//   board.js     the palette and the boards painted by hand (Paint's guide, the co-occurrence edit)
//   paint.js     Paint, Remix and Morph: several of the session's models
//   app.js       this file: the modes and the wiring of the page's controls (init)
//   cooc.js      Co-occurrence mode
// A file's top-level code uses only what earlier files define; functions call each other freely.
"use strict";

// The mode of section 3 (view, inpaint, paint, morph, cooc): its panel shown, what it needs said.
function setMode(mode) {
  clearStrip();  // the seeds are of View's Generate
  const inpaint = mode === "inpaint";
  document.body.classList.toggle("inpaint", inpaint);
  $("inpaint").hidden = !inpaint;
  $("paint").hidden = mode !== "paint";
  $("morph").hidden = mode !== "morph";
  $("cooc").hidden = mode !== "cooc";
  if (mode === "cooc") coocShown();
  if (inpaint) { inpaintHint(); showEditor(); }
  if (mode === "paint") {
    // Said first: the canvas is sized for the room under the message (0.62; 0.61 said the hint after, and a line of it
    // pushed the canvas's foot out of the window)
    if (state.models.length < 2) sayPaint(PAINT_HINT); else paintPicked();
    resizeGuide();
    sizeGuide();  // sized for the window now that it is shown, and brought into view
    intoView($("guide-box"));
  }
  if (mode === "morph" && state.models.length < 2) sayMorph(MORPH_HINT);
  else if (mode === "morph") morphPicked();
}

// The mode's picture to paint on (Inpaint's, Paint's canvas, Co-occurrence's edit) sized again for a window resized (a
// phone turned, a window made smaller), a moment after the last resize: 0.61 kept the size it had for the window the
// mode was chosen in, a canvas sized for a tall window cut off at the foot of a low one.
let resizeTimer = null;

function onResize() {
  clearTimeout(resizeTimer);
  resizeTimer = setTimeout(() => {
    if (!$("inpaint").hidden) sizeEditor();
    if (!$("paint").hidden) sizeGuide();
    if (!$("cooc").hidden) sizeCoocBoard();
  }, 100);
}

// The built-in menu shows the exemplar of the working model (or of the fit running). Picking the one it
// shows fits it again (after a cancel, or with other fit settings): while its list is open the menu shows a
// hidden copy of that option, so that any pick is a change; put back when the list closes with no pick.
function wireBuiltinMenu(select) {
  const copy = document.createElement("option");
  copy.hidden = true;
  copy.value = "";
  const showSource = () => {  // the option of state.source's built-in ("choose..." for none)
    copy.remove();
    select.value = (state.source && state.source.builtin) || "";
  };
  const open = () => {
    if (select.selectedOptions[0] === copy) return;  // open already
    copy.textContent = select.selectedOptions[0].textContent;
    select.insertBefore(copy, select.selectedOptions[0]);  // Down in the list: the option shown
    select.selectedIndex = copy.index;
  };
  // A key that moves the closed menu's choice (an arrow, Home, End, a page key, a letter: the browser fires a
  // change per option passed) is down: that change is browsing, fitted once the choice settles (fitBuiltinSoon).
  let browsing = false;
  select.addEventListener("pointerdown", () => { browsing = false; open(); });
  select.addEventListener("mousedown", open);
  select.addEventListener("keydown", (e) => {  // the keys that open the list
    const closed = select.selectedOptions[0] !== copy;
    browsing = closed && !e.altKey && !e.ctrlKey && !e.metaKey && BROWSE_KEY.test(e.key);
    if (e.key === " " || e.key === "F4" || (e.altKey && (e.key === "ArrowDown" || e.key === "ArrowUp"))) open();
    else if (e.key === "Escape" && !closed) showSource();
    else if (e.key === "Enter" && closed) settleBuiltin();  // the choice made: fitted now
  });
  select.addEventListener("keyup", () => { browsing = false; });
  select.addEventListener("blur", () => {
    browsing = false;
    if (select.selectedOptions[0] === copy) showSource(); else settleBuiltin();  // left: the choice made
  });
  select.addEventListener("change", () => {
    copy.remove();
    if (!select.value) { withdrawBuiltin(); showSource(); } else if (browsing) fitBuiltinSoon(select.value);
    else { withdrawBuiltin(); fitBuiltin(select.value); }
  });
}

// Each mode's long help (p.help.long) cut to its first lines in a narrow window (style.css), and a "more" button after
// it that shows it whole (and "less" again); the button is shown in a narrow window only.
function wireLongHelp() {
  for (const help of document.querySelectorAll("p.help.long")) {
    const more = document.createElement("button");
    help.id = help.id || `${help.parentElement.id}-help`;
    more.type = "button";
    more.className = "more-help secondary";
    more.textContent = "more";
    more.setAttribute("aria-controls", help.id);
    more.setAttribute("aria-expanded", "false");
    more.addEventListener("click", () => {
      const open = help.classList.toggle("open");
      more.textContent = open ? "less" : "more";
      more.setAttribute("aria-expanded", String(open));
    });
    help.after(more);
  }
}

// Enter in a mode's field presses the mode's button, as Enter in a field of Generate generates (0.63; 0.62 did
// nothing): not while a work runs (its button reads Stop), nor when the button is off.
const ENTER_PRESSES = {
  "inpaint-seed": "fill", "inpaint-count": "fill", "extend-height": "extend-go", "extend-width": "extend-go",
  transition: "paint-go", "paint-seed": "paint-go", "morph-height": "morph-go", "morph-width": "morph-go",
  "morph-seed": "morph-go", "cooc-length": "cooc-morph-go", "cooc-morph-seed": "cooc-morph-go",
  "cooc-boost-a": "cooc-edit-go", "cooc-boost-b": "cooc-edit-go", "cooc-boost-factor": "cooc-edit-go",
  "cooc-edit-seed": "cooc-edit-go",
};

function onEnterKey(event) {
  const go = event.key === "Enter" && !event.isComposing && $(ENTER_PRESSES[event.target.id] || "");
  if (!go || state.busy || go.disabled) return;
  event.preventDefault();
  go.click();
}

// The keys that move a closed select's choice: arrows, Home, End, Page Up and Down, a letter or digit (type-ahead).
const BROWSE_KEY = /^(Arrow(Up|Down|Left|Right)|Home|End|Page(Up|Down)|\S)$/u;

// Every control of the page to its handler (cooc.js wires its own), the builtins listed; then the page is ready.
async function init() {
  const select = $("builtin");
  try {
    const api = await (await fetch("/api")).json();
    state.coocMissing = api.cooc === false;  // no PyTorch on the server: Co-occurrence mode says so
    for (const name of api.builtins) {
      const option = document.createElement("option");
      option.value = name;
      option.textContent = `builtin:${name}`;
      select.append(option);
    }
  } catch (e) {
    say("the server's API did not answer", true);
  }
  wireBuiltinMenu(select);
  wireLongHelp();
  // Each chooser emptied once read: the same file chosen again (after a refusal, say) is a change
  $("file").addEventListener("change", (e) => { fitFile(e.target.files[0]); e.target.value = ""; });
  $("model-file").addEventListener("change", (e) => { uploadModel(e.target.files[0]); e.target.value = ""; });
  $("maps").addEventListener("change", (e) => setMapFiles(e.target.files));
  $("maps-clear").addEventListener("click", () => setMapFiles([]));
  $("maps-use").addEventListener("click", useOfferedMaps);
  $("download-maps").addEventListener("click", downloadMaps);
  $("history-forget").addEventListener("click", forgetHistory);
  $("cancel").addEventListener("click", cancelFit);
  $("gen-form").addEventListener("submit", onGenerate);
  $("strip-go").addEventListener("click", onStrip);
  $("gen-form").addEventListener("invalid", onInvalidField, true);  // said in the status too
  for (const radio of document.querySelectorAll("input[name=mode]")) {
    radio.addEventListener("change", () => { if (radio.checked) setMode(radio.value); });
  }
  $("brush").addEventListener("input", () => { $("brush-size").textContent = `${$("brush").value} px`; });
  $("clear").addEventListener("click", onClear);
  $("undo").addEventListener("click", undoInpaint);
  document.addEventListener("keydown", onUndoKey);
  document.addEventListener("keydown", onEnterKey);
  $("fill").addEventListener("click", onFill);
  $("extend-go").addEventListener("click", onExtend);
  for (const id of ["extend-height", "extend-width"]) $(id).addEventListener("input", growTyped);
  $("picture").addEventListener("change", (e) => onPicture(e.target.files[0]));
  // Each chooser emptied once read, as above
  $("mask-file").addEventListener("change", (e) => { onMaskFile(e.target.files[0]); e.target.value = ""; });
  $("guide-file").addEventListener("change", (e) => { onGuideFile(e.target.files[0]); e.target.value = ""; });
  const mask = $("mask");
  mask.addEventListener("pointerdown", onBrushDown);
  mask.addEventListener("pointermove", onBrushMove);
  mask.addEventListener("pointerup", onBrushUp);
  mask.addEventListener("pointercancel", onBrushUp);
  mask.addEventListener("pointerleave", () => { $("brush-cursor").hidden = true; });
  wireBoard(guide);
  $("paint-brush").addEventListener("input", () => {
    $("paint-brush-size").textContent = `${$("paint-brush").value} px`;
  });
  $("paint-reset").addEventListener("click", resetGuide);
  $("paint-undo").addEventListener("click", undoPaint);
  for (const id of ["height", "width"]) {
    $(id).addEventListener("change", () => { if (!$("paint").hidden) resizeGuide(); });
  }
  $("paint-go").addEventListener("click", () => onPaintGenerate(false));
  $("paint-result-go").addEventListener("click", goToPainted);
  $("cooc-result-go").addEventListener("click", goToPainted);
  $("remix-go").addEventListener("click", () => onPaintGenerate(true));
  $("morph-go").addEventListener("click", onMorph);
  for (const id of ["morph-a", "morph-b"]) $(id).addEventListener("change", morphPicked);
  $("zoom").addEventListener("change", (e) => {
    document.body.classList.toggle("zoom", e.target.checked);
    exemplarCaption();  // an enlarged exemplar's factor said only while it is enlarged
    if (!$("inpaint").hidden) sizeEditor();  // Inpaint's picture too (0.63)
  });
  $("exemplar").addEventListener("load", (e) => enlargeSmall(e.target));
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
  window.addEventListener("pagehide", onPageHide);
  window.addEventListener("resize", onResize);
  wireKeptFields();  // Generate's fields, the fit settings and the modes' kept across a reload (history.js)
  await restoreHistory();  // the recent results of before a reload
  await restoreFields();  // the fields
  await restoreWorking();  // and its working model
  await restoreShown();  // and the result shown, beside its exemplar
  document.body.dataset.ready = "1";
}

document.addEventListener("DOMContentLoaded", init);
