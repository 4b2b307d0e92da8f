"""HTML report pages that link every figure and table a run produced."""

from __future__ import annotations

import html
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from appeal.atomic import atomic_write_text

__all__ = ["ReportSection", "write_index_html", "table_html"]

_STYLE = """
*{box-sizing:border-box}
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{border-bottom:2px solid #444}h2{margin-top:2em;border-bottom:1px solid #ccc}
h3,figcaption,li,p{overflow-wrap:anywhere}
figure{margin:1em 0;max-width:100%}
img{max-width:100%;height:auto;border:1px solid #ddd;margin:.5em 0}
pre{max-width:100%;overflow-x:auto}
.table-wrap{max-width:100%;overflow-x:auto;margin:.5em 0;border:1px solid #eee}
table{border-collapse:collapse;font-size:.85em}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right;white-space:nowrap}
.failed{color:#b00}.muted{color:#777;font-size:.85em}
"""


def _scroll_tables(text: str) -> str:
    """Put every ``<table>`` of ``text`` in a box that scrolls sideways (the page keeps its width)."""
    return re.sub(r"(<table\b.*?</table>)", r"<div class='table-wrap'>\1</div>", text, flags=re.S)


@dataclass
class ReportSection:
    """One section of a report: a heading, Markdown text, figures and tables (paths)."""

    title: str
    text: str = ""
    figures: list[Path] = field(default_factory=list)
    tables: list[Path] = field(default_factory=list)
    links: list[Path] = field(default_factory=list)
    failed: str | None = None
    note: str = ""


_UNSAFE_LINK = re.compile(r"""(href|src)=(["'])\s*(?:javascript|vbscript|data):[^"']*\2""", re.I)


def _md(text: str) -> str:
    """Markdown as HTML, with raw HTML shown as text: a report's text holds values read from data
    files (conditions, levels, ids), and a level ``<img src=x onerror=...>`` must not run in the
    lab's browser; links to ``javascript:``/``data:`` URLs are dropped the same way."""
    import markdown

    md = markdown.Markdown(extensions=["tables"])
    md.preprocessors.deregister("html_block")
    md.inlinePatterns.deregister("html")
    return _scroll_tables(_UNSAFE_LINK.sub(r"\1=\2#\2", md.convert(text)))


def table_html(path: Path, max_rows: int = 25) -> str:
    """The first ``max_rows`` rows of a CSV/TSV/JSON table as an HTML table."""
    import pandas as pd

    suffix = path.suffix.lower()
    try:
        if suffix in (".csv", ".tsv"):
            df = pd.read_csv(path, sep="\t" if suffix == ".tsv" else ",")
        else:
            return ""
    except Exception:  # noqa: BLE001 - a table we cannot parse is still linked
        return ""
    more = f"<p class='muted'>{len(df) - max_rows} more rows in the file</p>" if len(df) > max_rows else ""
    return _scroll_tables(df.head(max_rows).to_html(index=False, float_format=lambda v: f"{v:.4g}", border=0)) + more


def _rel(path: Path, root: Path) -> str:
    return html.escape(os.path.relpath(path, root).replace(os.sep, "/"))


def write_index_html(path: str | Path, title: str, sections: Sequence[ReportSection], intro: str = "") -> Path:
    """Write an HTML page linking every figure and table of ``sections``.

    Parameters
    ----------
    path : str | Path
        The HTML file to write; links are relative to its folder.
    title : str
        Page title.
    sections : sequence of ReportSection
        The content.
    intro : str
        Markdown shown under the title.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    root = path.parent
    parts = [f"<!doctype html><html><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{html.escape(title)}</title>",
             f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>", _md(intro) if intro else ""]
    toc = "".join(f"<li><a href='#s{i}'>{html.escape(s.title)}</a></li>" for i, s in enumerate(sections))
    parts.append(f"<ul>{toc}</ul>")
    for i, sec in enumerate(sections):
        parts.append(f"<h2 id='s{i}'>{html.escape(sec.title)}</h2>")
        if sec.failed:
            parts.append(f"<p class='failed'>This stage failed: {html.escape(sec.failed)}</p>")
        if sec.text:
            parts.append(_md(sec.text))
        if sec.note:
            parts.append(f"<p class='muted'>{html.escape(sec.note)}</p>")
        for fig in sec.figures:
            rel = _rel(Path(fig), root)
            if Path(fig).suffix.lower() in (".png", ".jpg", ".jpeg", ".svg", ".gif"):
                parts.append(f"<figure><a href='{rel}'><img src='{rel}' alt='{rel}'></a><figcaption class='muted'>{rel}</figcaption></figure>")
            else:
                parts.append(f"<p><a href='{rel}'>{rel}</a></p>")
        for tab in sec.tables:
            rel = _rel(Path(tab), root)
            parts.append(f"<h3><a href='{rel}'>{rel}</a></h3>{table_html(Path(tab))}")
        if sec.links:
            items = "".join(f"<li><a href='{_rel(Path(p), root)}'>{_rel(Path(p), root)}</a></li>" for p in sec.links)
            parts.append(f"<ul>{items}</ul>")
    parts.append("</body></html>\n")
    return atomic_write_text(path, "\n".join(parts))
