"""A campaign report as one self-contained HTML page: the headline first (success rate with its
95 % interval, Δv, safety, timings), then the report's tables and figures.

Self-contained: the figures are inlined as PNG data URIs and the style sheet is in the page;
there is no script and nothing is loaded from a network, so the file can be mailed or archived
and opens the same anywhere. The body is the campaign's ``report.md`` (the same numbers, one
source), turned into HTML by :func:`markdown_to_html`, which knows the few constructs the
reports use: headings, paragraphs, bullet lists, pipe tables, images and inline code.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

STYLE = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; margin: 2em auto; max-width: 72em;
       padding: 0 1.5em; color: #1d2228; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { margin-top: 1.8em; border-bottom: 1px solid #d5dae0; }
.headline { display: grid; grid-template-columns: repeat(auto-fit, minmax(14em, 1fr)); gap: 0.8em; margin: 1.2em 0; }
.card { border: 1px solid #d5dae0; border-radius: 6px; padding: 0.7em 1em; background: #f7f9fb; }
.card .label { font-size: 0.85em; color: #56606b; } .card .value { font-size: 1.35em; font-weight: 600; }
.card .note { font-size: 0.8em; color: #56606b; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #d5dae0; padding: 0.25em 0.6em; text-align: left; }
th { background: #eef1f4; } tr:nth-child(even) td { background: #fafbfc; }
img { max-width: 100%; border: 1px solid #e3e7eb; margin: 0.5em 0; }
code { background: #eef1f4; padding: 0 0.25em; border-radius: 3px; }
"""


def _inline(text: str) -> str:
    """Escape, then `code` spans."""
    out = html.escape(text)
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", out)


def _image(alt: str, src: str, base: Path) -> str:
    path = base / src
    if path.suffix.lower() == ".png" and path.is_file():
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        return f'<figure><img alt="{html.escape(alt)}" src="data:image/png;base64,{data}"></figure>'
    return f"<p>(figure {html.escape(src)} missing)</p>"


def markdown_to_html(markdown: str, base: Path) -> str:
    """The report's Markdown subset as HTML; images read from ``base`` and inlined."""
    out: list[str] = []
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        if m := re.match(r"^(#{1,6})\s+(.*)$", line):
            level = len(m.group(1))
            out.append(f"<h{level}>{_inline(m.group(2))}</h{level}>")
            i += 1
        elif m := re.match(r"^!\[(.*?)\]\((.*?)\)\s*$", line):
            out.append(_image(m.group(1), m.group(2), base))
            i += 1
        elif line.lstrip().startswith("|"):
            rows = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
                if not all(re.fullmatch(r":?-{3,}:?", c) for c in cells):
                    rows.append(cells)
                i += 1
            head, body = rows[0], rows[1:]
            out.append('<div class="scroll"><table><thead><tr>' + "".join(f"<th>{_inline(c)}</th>" for c in head) + "</tr></thead><tbody>"
                       + "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in body)
                       + "</tbody></table></div>")
        elif line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{_inline(lines[i][2:])}</li>")
                i += 1
            out.append("<ul>" + "".join(items) + "</ul>")
        else:
            para = []
            while i < len(lines) and lines[i].strip() and not re.match(r"^(#|!\[|\||- )", lines[i].lstrip()):
                para.append(lines[i].strip())
                i += 1
            out.append(f"<p>{_inline(' '.join(para))}</p>")
    return "\n".join(out)


def headline_cards(cards: list[tuple[str, str, str]]) -> str:
    """``[(label, value, note), ...]`` as the row of cards at the top of the page."""
    return '<section class="headline">' + "".join(
        f'<div class="card"><div class="label">{html.escape(label)}</div><div class="value">{html.escape(value)}</div>'
        f'<div class="note">{html.escape(note)}</div></div>' for label, value, note in cards) + "</section>"


def write_html(path: Path, title: str, cards: list[tuple[str, str, str]], markdown: str) -> Path:
    """The self-contained page: ``title``, the headline ``cards``, then ``markdown`` (its first
    ``#`` heading is replaced by ``title``); images relative to ``path``'s folder are inlined."""
    body = re.sub(r"^#\s+.*\n", "", markdown, count=1)
    page = (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>\n"
            f"<h1>{html.escape(title)}</h1>\n{headline_cards(cards)}\n{markdown_to_html(body, path.parent)}\n"
            f"</body></html>\n")
    path.write_text(page, encoding="utf-8")
    return path
