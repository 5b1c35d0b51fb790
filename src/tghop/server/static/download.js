// tghop serve's page: downloads, a link to a file of the server or the maps of the material shown
// as one ZIP (made here: nothing fetched for it).
"use strict";

// A download link for `href` saved as `name` (hidden when href is empty).
function offerDownload(link, href, name) {
  link.hidden = !href;
  if (!href) return;
  link.href = href;
  link.setAttribute("download", name);
}

// A name's characters safe in a file's name: runs of other characters than letters and digits of any script,
// their combining marks, ".", "_" and "-" as one "-", none at either end, at most 40 characters (the server's
// Content-Disposition makes the same of ?name=: requests.file_stem).
function fileStem(text) {
  const kept = String(text ?? "").normalize("NFC").replace(/[^\p{L}\p{N}\p{M}._-]+/gu, "-")
    .replace(/^[-._]+|[-._]+$/gu, "");
  return Array.from(kept).slice(0, 40).join("").replace(/[-._]+$/u, "");
}

// A model's part of a file name, from the page's name of it ("builtin:bricks + 2 maps", "wall.jpg"): "bricks",
// "wall". A material's albedo word goes ("rock_albedo.png + 2 maps", "Rock023_2K_Color.jpg + 2 maps": "rock",
// "Rock023_2K"): its maps' files are named after it (tghop-rock_albedo-256x256-seed1_normal.png was a normal map).
function modelStem(name) {
  const text = String(name || "").replace(/^builtin:/, "");
  const material = / \+ \d+ maps?$/.test(text);
  const plain = text.replace(/ \+ \d+ maps?$/, "").replace(/\.[A-Za-z0-9]+$/, "");
  const bare = material ? fileStem(plain.replace(ALBEDO_WORD, (word, before) => before.replace(/[-_. ]$/, ""))) : "";
  return bare || fileStem(plain) || "model";
}

// An albedo's word in a file's name, with the separator before it (ALBEDO_NAME's words: fit.js).
const ALBEDO_WORD = /(^|[^a-z])(albedo|diffuse|diff|(base)?colou?r)(?=[^a-z]|$)/i;

// The model file's download: its name as the server's Content-Disposition gives it (routes/models.py,
// download_name), which wins over the link's own where they differ.
function modelDownload(id, stem) {
  return [`/api/models/${id}/file?name=${encodeURIComponent(stem)}`, `tghop-${stem}-${id.slice(0, 12)}.npz`];
}

// A result's file name, without ".png": tghop-<model(s)>[-<what>]-<H>x<W>-seed<N>[-tile][_<k>] (`models`: their
// stems; `fill` k: a strip's fill k of the seed, numbered as tghop inpaint --count numbers OUT_k.png, 0.61).
function resultBase(seed, what, { models, size, tile, fill }) {
  const parts = ["tghop", ...models, ...(what ? [what] : []), `${size[0]}x${size[1]}`, `seed${fileStem(seed)}`];
  return parts.join("-") + (tile ? "-tile" : "") + (fill ? `_${fill}` : "");
}

// The working model's stem (its name in state.models), "model" for none.
function workingStem() {
  const m = state.models.find((model) => model.id === state.modelId);
  return m ? m.stem : "model";
}

// Map i's file, as tghop synth names it: the albedo's <base>.png, each other map's <base>_<suffix>.png (the
// server's suffix: tghop.material_files.map_suffixes; its name where none came).
function mapFile(shown, i) {
  return i ? `${shown.base}_${shown.maps[i].suffix || shown.maps[i].name}.png` : `${shown.base}.png`;
}

// One download of every map: a ZIP of the PNGs as tghop synth names them (several downloads at once
// made browsers ask leave for each).
async function downloadMaps() {
  const shown = state.shown;
  if (shown) await downloadZip(shown.base, shown.maps);
}

// The maps of a result whose files are named from `base` (mapFile) saved as one ZIP, `base`.zip.
async function downloadZip(base, maps) {
  const zip = await zipOf(maps.map((m, i) => ({ name: mapFile({ base, maps }, i), blob: m.blob })));
  const link = document.createElement("a");
  link.href = URL.createObjectURL(zip);
  link.download = `${base}.zip`;
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
      view.setUint16(at, 20, true);  // needed: version 2.0; then the flags, method 0 (stored), time 0
      view.setUint16(at + 2, 0x800, true);  // bit 11: the name is UTF-8 (a model's stem keeps any script's letters;
      // without it unzip programs read it as code page 437, 0.59's "Gr├╢├ƒe")
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
