"""The report page: one self-contained HTML file, images embedded as data URIs.

A short script marks every image's load state (``data-loaded`` = 1 or 0, and a visible
note under a broken one) and sets ``data-ready`` on the body when the page has loaded —
for people, and for the headless-browser test that reads the rendered DOM.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Sequence
from typing import Any

from .section import Section

__all__ = ["render_html"]

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 980px; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.45; }
nav ul { columns: 2; } figure { margin: 1.2em 0; } img { max-width: 100%; }
figcaption { font-size: 0.9em; color: #444; } .thesis { border-left: 3px solid #999;
padding-left: 0.6em; color: #333; font-size: 0.92em; } table { border-collapse: collapse;
font-size: 0.85em; margin: 0.8em 0; } td, th { border: 1px solid #ccc; padding: 2px 6px; }
pre { font-size: 0.78em; overflow-x: auto; background: #f6f6f6; padding: 0.5em; }
.numbers { font-size: 0.8em; color: #555; } .broken { color: #b00; font-weight: bold; }
"""

_SCRIPT = """
window.addEventListener('load', () => {
  for (const img of document.images) {
    const ok = img.complete && img.naturalWidth > 0;
    img.dataset.loaded = ok ? '1' : '0';
    if (!ok) img.insertAdjacentHTML('afterend', '<p class="broken">image failed to load</p>');
  }
  document.body.dataset.ready = '1';
});
// sortable tables: a click on a header sorts by that column (numbers as numbers)
document.querySelectorAll('table.sortable th').forEach((th, col) => {
  th.style.cursor = 'pointer';
  th.addEventListener('click', () => {
    const body = th.closest('table').tBodies[0];
    const key = (tr) => { const t = tr.cells[th.cellIndex].textContent.trim();
                          const x = parseFloat(t); return isNaN(x) ? t : x; };
    const dir = th.dataset.dir === 'asc' ? -1 : 1;
    th.dataset.dir = dir === 1 ? 'asc' : 'desc';
    [...body.rows].sort((a, b) => { const p = key(a), q = key(b);
      return (p > q ? 1 : p < q ? -1 : 0) * dir; }).forEach((r) => body.appendChild(r));
  });
});
"""


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v[:12]) + (", …" if len(v) > 12 else "") + "]"
    return html.escape(str(v))


def _html_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A sortable HTML table (click a header; the page's script sorts numbers as numbers)."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows
    )
    return f"<table class='sortable'><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


_RULE = re.compile(r"^\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?\s*$")


def markdown_to_html(text: str) -> str:
    """A command's Markdown output as HTML: pipe tables become ``<table>``s, headings and
    other lines paragraphs (``turntable bench``'s table, the benchmark's leaderboard)."""
    out: list[str] = []
    block: list[list[str]] = []

    def flush() -> None:
        if block:
            out.append(_html_table(block[0], block[1:]))
            block.clear()

    for line in text.splitlines():
        st = line.strip()
        if st.startswith("|"):
            if not _RULE.match(st):
                block.append([c.strip() for c in st.strip("|").split("|")])
            continue
        flush()
        if st.startswith("#"):
            out.append(f"<h3>{html.escape(st.lstrip('#').strip())}</h3>")
        elif st:
            out.append(f"<p>{html.escape(st)}</p>")
    flush()
    return "".join(out)


def _table(t: dict[str, Any]) -> str:
    cap = f"<p><b>{html.escape(t.get('caption', ''))}</b></p>"
    if "text" in t:  # a command's Markdown output: its tables as HTML tables
        return cap + markdown_to_html(t["text"])
    return cap + _html_table(t["header"], t["rows"])


# display units for the numbers under a figure (summary.json keeps SI): name suffix →
# (factor, unit as the thesis writes it)
DISPLAY_UNITS = {
    "_V_per_s": (1e-6, "V/µs"),
    "_um": (1.0, "µm"),
    "_m": (1e6, "µm"),
    "_urad": (1.0, "µrad"),
    "_rad": (1e3, "mrad"),
    "_mrad": (1.0, "mrad"),
    "_s": (1.0, "s"),
    "_N": (1.0, "N"),
    "_V": (1.0, "V"),
    "_J": (1.0, "J"),
}


def display_number(name: str, value: Any) -> tuple[str, str]:
    """(label, text) of a figure's number in the thesis's units: ``slew_1V_step_V_per_s``
    = 9e5 → ("slew 1V step [V/µs]", "0.9")."""
    for suffix, (factor, unit) in DISPLAY_UNITS.items():
        if name.endswith(suffix) and isinstance(value, int | float) and not isinstance(value, bool):
            label = name[: -len(suffix)].replace("_", " ")
            return f"{label} [{unit}]", f"{value * factor:.4g}"
    return name.replace("_", " "), _fmt(value)


def _image(im: dict[str, Any]) -> str:
    src = f"data:{im['mime']};base64,{base64.b64encode(im['data']).decode('ascii')}"
    thesis = f"<p class='thesis'>Thesis: {html.escape(im['thesis'])}</p>" if im["thesis"] else ""
    nums = im.get("numbers") or {}
    num_html = (
        "<p class='numbers'>"
        + "; ".join(
            f"{html.escape(label)} = {text}"
            for label, text in (display_number(k, v) for k, v in nums.items())
        )
        + "</p>"
        if nums
        else ""
    )
    return (
        f"<figure id='{html.escape(im['name'])}'>"
        f"<img src='{src}' alt='{html.escape(im['caption'])}'>"
        f"<figcaption>{html.escape(im['caption'])}</figcaption>{thesis}{num_html}</figure>"
    )


def render_html(sections: Sequence[Section], summary: dict[str, Any]) -> str:
    """The page for the sections (``summary``: summary.json's content, for the header)."""
    toc = "".join(f"<li><a href='#{s.id}'>{html.escape(s.title)}</a></li>" for s in sections)
    body = []
    for s in sections:
        parts = [f"<h2>{html.escape(s.title)}</h2>", f"<p>{html.escape(s.intro)}</p>"]
        parts += [_table(t) for t in s.tables]
        parts += [_image(im) for im in s.images]
        parts.append(f"<p class='numbers'>section computed in {s.wall_s:.1f} s</p>")
        body.append(f"<section id='{s.id}'>{''.join(parts)}</section>")
    quick = (
        " (quick run: shortened computations, not the reported figures)"
        if summary.get("quick")
        else ""
    )
    return (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        "<title>piezo-turntable report</title>"
        f"<style>{_CSS}</style></head><body>"
        f"<h1>piezo-turntable: what the environment knows{html.escape(quick)}</h1>"
        "<p>The piezoelectric stick–slip turntable of M. Schepers' M.Sc. thesis, simulated "
        "with the real parameters (Table D.1). Every number on this page is in "
        f"summary.json. Total time {summary['wall_s']:.0f} s on "
        f"{html.escape(str(summary.get('machine', 'this machine')))}; each section states "
        "its own time.</p>"
        f"<nav><ul>{toc}</ul></nav>{''.join(body)}"
        f"<script>{_SCRIPT}</script></body></html>"
    )
