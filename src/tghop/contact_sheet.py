"""The contact sheet of a batch (:mod:`tghop.batch`): one HTML page in OUTDIR that shows
each exemplar's thumbnail, status and outputs, with relative links and no external
resources, so that the folder can be moved or served as it is."""

from __future__ import annotations

import html
import os
from pathlib import Path
from urllib.parse import quote

from ._errors import TGHopError, terminal_line

__all__ = ["write_contact_sheet", "CONTACT_SHEET"]

#: The contact sheet's file name, in OUTDIR.
CONTACT_SHEET = "index.html"


#: Every image of the sheet is fetched as it comes near the window, not with the page: the sheet of a batch
#: of thousands fetched all their thumbnails and whole outputs (for 96-pixel previews) before it was
#: ready (docs/batch.md, "Thousands of exemplars").
LAZY = ' loading="lazy" decoding="async"'


def _href(path: str) -> str:
    """A relative link to ``path``: its bytes percent-encoded, those of a name that is not UTF-8 too (0.64: the sheet of
    such a folder or exemplar failed to be written, "surrogates not allowed")."""
    return quote(os.fsencode(path), safe="/")


def _esc(text) -> str:
    """``text`` for the page: HTML-escaped, a file name that is not UTF-8 as a terminal shows it (U+FFFD)."""
    return html.escape(terminal_line(text))


def _anchor(name: str) -> str:
    """A row's id, by its exemplar's name (a folder name: no space, unique)."""
    return "x-" + _esc(name)


def _failed_links(records) -> str:
    """Above the table, a link to each exemplar that failed (or was interrupted), folded: among 3,000 rows
    their 314 were found only by scrolling through all of them."""
    failed = [r for r in records if r.get("status") != "ok"]
    if not failed:
        return ""
    links = ", ".join(f'<a href="#{_anchor(r["name"])}">{_esc(r["name"])}</a>' for r in failed)
    return f"\n<details><summary>The {len(failed):,} not done</summary><p>{links}</p></details>"


def write_contact_sheet(outdir, records, *, total=None, ledger=None) -> Path:
    """``OUTDIR/index.html``: per exemplar its thumbnail, name, source, status (with the
    error), time and outputs (linked, relative paths; no external resources); ``total``
    exemplars in the batch (more than the records: the rest not finished); ``ledger``: the
    name of the ledger file in OUTDIR to link (None: no link)."""
    from .imageio import write_atomic

    outdir = Path(outdir)
    ok = sum(r.get("status") == "ok" for r in records)
    rows = []
    for r in records:
        esc = _esc
        thumb = (f'<img src="{_href(r["thumbnail"])}" alt="{esc(r["name"])}" width="96"{LAZY}>'
                 if r.get("thumbnail") else "")
        outputs = " ".join(f'<a href="{_href(f)}"><img src="{_href(f)}" alt="{esc(f)}" height="96"{LAZY}></a>'
                           for f in r.get("outputs") or [])
        model = f'<a href="{_href(r["model"])}">model</a>' if r.get("model") else ""
        status = esc(r.get("status", "?")) + (" (earlier run)" if r.get("skipped") else "")
        error = f'<div class="error">{esc(r["error"])}</div>' if r.get("error") else ""
        seconds = f"{r['seconds']:.1f} s" if isinstance(r.get("seconds"), (int, float)) else ""
        rows.append(f'<tr id="{_anchor(r["name"])}" class="{esc(r.get("status", ""))}"><td>{thumb}</td><td>'
                    f'<b>{esc(r["name"])}</b><br><small>{esc(str(r.get("source", "")))}</small></td>'
                    f"<td>{status}{error}</td><td>{seconds}</td><td>{outputs}</td><td>{model}</td></tr>")
    left = (total or 0) - len(records)
    unfinished = f" {left:,} not finished yet: run the same command again." if left > 0 else ""
    link = f'Ledger: <a href="{_href(ledger)}">{_esc(ledger)}</a>.' if ledger else ""
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>tghop batch: {ok:,} of {max(total or 0, len(records)):,} done</title>
<style>body{{font-family:sans-serif;margin:1em}}table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:4px;vertical-align:top}}tr.failed{{background:#fee}}
.error{{color:#a00;max-width:30em}}img{{image-rendering:pixelated}}</style></head>
<body><h1>tghop batch</h1><p>{ok:,} of {len(records):,} exemplars done, {len(records) - ok:,} failed.{unfinished}
{link}</p>{_failed_links(records)}
<table><tr><th>exemplar</th><th>name</th><th>status</th><th>time</th><th>outputs</th><th>model</th></tr>
{chr(10).join(rows)}
</table></body></html>
"""
    path = outdir / CONTACT_SHEET
    write_atomic(path, lambda fh: fh.write(page.encode("utf-8")), what="contact sheet", error=TGHopError)
    return path
