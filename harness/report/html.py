"""report.html: report.md rendered as one page (inline CSS; the figures linked from figures/, or embedded as base64
PNG in a self-contained page).

report.md is the single source, so every section anyone adds to it appears in the HTML too. The renderer knows the
subset of Markdown the report uses (headings, pipe tables, bullet lists with indented continuation lines, paragraphs,
images on their own line, `code`) and adds what Markdown cannot say: table cells of drifts and errors are coloured on
a log scale, statuses by severity.
"""
from __future__ import annotations

import base64
import html
import math
import re
from pathlib import Path

from ...reference.integrals import INTEGRALS

# Log10 range of the colour scale: 1e-16 (round-off) is green, 1 (nothing left of the quantity) is red.
GRADE_RANGE = (-16.0, 0.0)
STATUS_COLOURS = {"ok": "#d9f2d9", "diverged": "#ffd699", "failed": "#ff9f9f", "skipped": "#e0e0e0"}
# Headers whose cells are coloured by size: the registry's graded drift columns (reference.integrals) and the errors.
GRADED_HEADERS = {*(i.short for i in INTEGRALS.values() if i.graded), "att_err", "omega_err", "error"}

CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 110em; padding: 0 1em; color: #222; }
h1 { border-bottom: 2px solid #444; } h2 { border-bottom: 1px solid #aaa; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0 1.2em; font-size: 0.85em; }
th, td { border: 1px solid #bbb; padding: 0.15em 0.3em; text-align: right; white-space: nowrap; }
th { background: #eee; white-space: normal; } th.n { white-space: nowrap; } td.t { text-align: left; white-space: normal; min-width: 6em; }
div.wide { max-width: 100%; overflow-x: auto; }
div.wide th:first-child, div.wide td:first-child { position: sticky; left: 0; z-index: 1; }
div.wide td:first-child:not([class^="g"]):not([class^="s-"]) { background: #fff; }
details.fold > summary { font-weight: normal; font-size: 1em; }
figure { margin: 0.5em 0 1.5em; } img { max-width: 100%; }
code { background: #f3f3f3; padding: 0 0.2em; }
.scale { display: inline-block; width: 16em; height: 0.9em; vertical-align: middle; border: 1px solid #999; }
nav#contents { background: #f7f7f7; border: 1px solid #ccc; padding: 0.3em 1em; columns: 2; font-size: 0.9em; }
nav#contents ul { margin: 0.2em 0; } details { margin: 0.4em 0; border-left: 3px solid #ccc; padding-left: 0.8em; }
details > summary { cursor: pointer; font-weight: bold; font-size: 1.1em; }
th.sortable { cursor: pointer; } input.filter { margin: 0.3em 0; width: 20em; }
"""
# Tables with more rows than this get a filter box; every table sorts by a click on a header.
FILTER_ROWS = 8
# The page's one script, inline (no CDN, works from a file): sort a table by a column (numbers numerically, '-'
# last), filter its rows by text, and open a case's <details> when a link or the address names it.
SCRIPT = """
document.querySelectorAll('table').forEach(function (table) {
  var rows = function () { return Array.prototype.slice.call(table.rows, 1); };
  Array.prototype.forEach.call(table.rows[0].cells, function (th, column) {
    th.classList.add('sortable'); th.title = 'sort';
    th.addEventListener('click', function () {
      var up = th.dataset.up !== '1'; th.dataset.up = up ? '1' : '0';
      var key = function (row) { var t = row.cells[column] ? row.cells[column].textContent.trim() : '';
        var x = parseFloat(t); return isNaN(x) || !/^[-+0-9.eE]+$/.test(t) ? [1, t] : [0, x]; };
      rows().sort(function (a, b) { var p = key(a), q = key(b);
        var c = p[0] - q[0] || (p[1] < q[1] ? -1 : p[1] > q[1] ? 1 : 0); return up ? c : -c; })
        .forEach(function (row) { table.tBodies[0].appendChild(row); });
    });
  });
  if (table.rows.length > %d) {
    var box = document.createElement('input'); box.className = 'filter'; box.placeholder = 'filter rows';
    box.addEventListener('input', function () { var text = box.value.toLowerCase();
      rows().forEach(function (row) {
        row.style.display = row.textContent.toLowerCase().indexOf(text) < 0 ? 'none' : ''; }); });
    table.parentNode.insertBefore(box, table);
  }
});
function openTarget() { var e = location.hash && document.getElementById(location.hash.slice(1));
  if (e && e.tagName === 'DETAILS' && !e.open) { e.open = true; e.scrollIntoView(); } }
window.addEventListener('hashchange', openTarget); openTarget();
""" % FILTER_ROWS
# The level-2 section whose level-3 subsections (one per case) fold away as <details>.
COLLAPSIBLE = "cases"
CASE_PREFIX = "case-"


def slug(text: str) -> str:
    """An ASCII id for a heading: 'Work–precision' -> 'work-precision'."""
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def grade_colour(value: float) -> str:
    """Background for a drift or error: log10 of the value on GRADE_RANGE, green (small) to red (large)."""
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    low, high = GRADE_RANGE
    position = 0.0 if value <= 0 else (min(max(math.log10(value), low), high) - low) / (high - low)
    # Pale version of RdYlGn (reversed): text stays readable on every cell.
    r, g, b, _ = colormaps["RdYlGn_r"](position)
    return to_hex((0.45 + 0.55 * r, 0.45 + 0.55 * g, 0.45 + 0.55 * b))


# Graded cells carry a class, one per GRADE_STEPS-th of a decade, not an inline colour: a fifth of the bytes in the
# default suite's tables.
GRADE_STEPS = 2


def grade_class(value: float) -> str:
    """The class of a drift or error cell: g0 (<= 1e-16) .. g32 (>= 1)."""
    low, high = GRADE_RANGE
    if value <= 0:
        return "g0"
    return f"g{round((min(max(math.log10(value), low), high) - low) * GRADE_STEPS)}"


def _grade_css() -> str:
    low, high = GRADE_RANGE
    levels = int((high - low) * GRADE_STEPS)
    rules = [f"td.g{k} {{ background: {grade_colour(10 ** (low + k / GRADE_STEPS))}; }}" for k in range(levels + 1)]
    rules += [f"td.s-{status} {{ background: {colour}; }}" for status, colour in STATUS_COLOURS.items()]
    return "\n".join(rules) + "\n"


def _graded(header: str) -> bool:
    return header in GRADED_HEADERS or header.endswith(("_drift", "_err", "_err_end"))


# Markdown's backslash escape (an ASCII punctuation character after a backslash: md_text writes them) or a code span.
_HELD = re.compile(r"\\([!-/:-@\[-`{-~])|(`[^`]*`)")
_MARK = re.compile("\ue000(\\d+)\ue001")  # a held piece's place while bold is found (private-use characters)


def _inline(text: str) -> str:
    """Markdown's inline subset: backslash escapes (a name md_text escaped shows as itself), `code` and **bold** (the
    verdicts' **FAIL**, What to use's **tie**); inside code nothing is bold and a backslash is itself."""
    held: list[str] = []

    def hold(m: re.Match) -> str:
        held.append(html.escape(m.group(1)) if m.group(1) else f"<code>{html.escape(m.group(2)[1:-1])}</code>")
        return f"\ue000{len(held) - 1}\ue001"

    text = re.sub(r"\*\*(\S(?:.*?\S)?)\*\*", r"<strong>\1</strong>", html.escape(_HELD.sub(hold, text)))
    return _MARK.sub(lambda m: held[int(m.group(1))] if int(m.group(1)) < len(held) else m.group(0), text)


def _cells(line: str) -> list[str]:
    """The cells of a pipe-table line; '\\|' is a literal bar."""
    inner = line.strip()[1:]
    inner = inner[:-1] if inner.endswith("|") and not inner.endswith("\\|") else inner
    return [cell.strip().replace("\\|", "|") for cell in re.split(r"(?<!\\)\|", inner)]


# A header this short stays on one line ("≤ 1e-12" broke after its hyphen in a squeezed column); longer ones wrap.
SHORT_HEADER = 12


def _table(lines: list[str]) -> str:
    header = _cells(lines[0])
    body = [_cells(line) for line in lines[2:]]
    # a name may break after an underscore (energy_drift, gibbs_hamiltonian): a table's width is its numbers', not
    # its names'
    out = ['<div class="wide"><table>',
           "<tr>" + "".join(f"<th>{_inline(h).replace('_', '_<wbr>')}</th>" if len(h) > SHORT_HEADER
                            else f'<th class="n">{_inline(h)}</th>' for h in header) + "</tr>"]
    for cells in body:
        row = []
        for name, cell in zip(header, cells):
            style, css_class = "", ""
            if name == "status" and cell in STATUS_COLOURS:
                css_class = f' class="s-{cell}"'
            elif _graded(name):
                try:
                    value = float(cell)
                except ValueError:
                    value = math.nan
                if math.isfinite(value):
                    css_class = f' class="{grade_class(abs(value))}"'
            elif cell and not re.fullmatch(r"[-+0-9.eE]+", cell):
                css_class = ' class="t"'
            row.append(f"<td{css_class}{style}>{_inline(cell).replace('_', '_<wbr>')}</td>")
        out.append("<tr>" + "".join(row) + "</tr>")
    return "\n".join(out + ["</table></div>"])


def _image(alt: str, source: str, images: dict[str, bytes], base: Path | None, embed: bool = True) -> str:
    """A figure: embedded as base64 (embed), or linked by its path relative to the page, at its own pixel size."""
    data = images.get(source)
    if data is None and base is not None and (base / source).is_file():
        data = (base / source).read_bytes()
    if data is None:
        return f"<p>(figure {html.escape(source)} not found)</p>"
    size = _png_size(data)
    dims = f' width="{size[0]}" height="{size[1]}"' if size else ""
    src = f"data:image/png;base64,{base64.b64encode(data).decode('ascii')}" if embed else html.escape(source)
    lazy = "" if embed else ' loading="lazy"'
    return (f'<figure><img alt="{html.escape(alt)}" src="{src}"{dims}{lazy}>'
            f"<figcaption>{html.escape(alt)}</figcaption></figure>")


def _png_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) px from a PNG's IHDR, None for anything else."""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or len(data) < 24:
        return None
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def _scale_legend() -> str:
    low, high = GRADE_RANGE
    stops = ", ".join(grade_colour(10 ** (low + (high - low) * i / 8)) for i in range(9))
    return (f'<p>Cell colours: drift or error on a log scale, <span class="scale" style="background: '
            f'linear-gradient(to right, {stops})"></span> from 1e{low:.0f} (green) to 1e{high:.0f} (red).</p>')


def render(markdown: str, images: dict[str, bytes] | None = None, base: Path | None = None,
           embed: bool = True) -> str:
    """The HTML page of a report.md. images: figure path as written in the Markdown -> PNG bytes; missing ones are
    read from `base` (the report's folder). embed: the figures inside the page (base64), else linked by their paths,
    relative to the page's folder."""
    images = images or {}
    lines = markdown.splitlines()
    body: list[str] = []
    paragraph: list[str] = []
    items: list[str] = []
    section_open = False

    def flush() -> None:
        if paragraph:
            body.append(f"<p>{_inline(' '.join(paragraph))}</p>")
            paragraph.clear()
        if items:
            body.append("<ul>" + "".join(f"<li>{_inline(item)}</li>" for item in items) + "</ul>")
            items.clear()

    i, title = 0, "stereodyn report"
    toc: list[tuple[int, str, str]] = []  # (level, id, text)
    section, details_open = "", False

    def close_details() -> None:
        nonlocal details_open
        if details_open:
            body.append("</details>")
            details_open = False

    while i < len(lines):
        line = lines[i]
        heading = re.match(r"(#{1,6}) (.*)", line)
        image = re.fullmatch(r"!\[([^\]]*)\]\(([^)]+)\)", line.strip())
        fold = re.fullmatch(r"<details><summary>(.*)</summary>", line.strip())
        if fold or line.strip() == "</details>":  # a section's own fold (the verdicts' passes), as GitHub shows it
            flush()
            body.append(f'<details class="fold"><summary>{_inline(fold.group(1))}</summary>' if fold
                        else "</details>")
        elif heading:
            flush()
            level, text = len(heading.group(1)), heading.group(2).strip()
            if level == 1:
                title = text
            if level == 2:
                close_details()
                if section_open:
                    body.append("</section>")
                section = slug(text)
                body.append(f'<section id="{section}">')
                section_open = True
                toc.append((2, section, text))
            if level == 3 and section == COLLAPSIBLE:
                close_details()
                anchor = CASE_PREFIX + slug(text)
                body.append(f'<details id="{anchor}"><summary>{_inline(text)}</summary>')
                details_open = True
                toc.append((3, anchor, text))
                i += 1
                continue
            anchor = "" if level == 2 else f' id="{slug(text)}"'  # a level-2 heading's id is its <section>'s
            body.append(f'<h{level}{anchor}>{_inline(text)}</h{level}>')
            if level == 2 and slug(text) == COLLAPSIBLE:  # the cases: their drift tables
                body.append(_scale_legend())
        elif line.startswith("|"):
            flush()
            block = []
            while i < len(lines) and lines[i].startswith("|"):
                block.append(lines[i])
                i += 1
            body.append(_table(block))
            continue
        elif image:
            flush()
            body.append(_image(image.group(1), image.group(2), images, base, embed))
        elif line.startswith("- "):
            if paragraph:
                flush()
            items.append(line[2:].strip())
        elif line.startswith("  ") and items:
            items[-1] += " " + line.strip()
        elif not line.strip():
            flush()
        else:
            if items:
                flush()
            paragraph.append(line.strip())
        i += 1
    flush()
    close_details()
    if section_open:
        body.append("</section>")
    first = next((k for k, part in enumerate(body) if part.startswith("<section")), len(body))
    body.insert(first, _contents(toc))
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{CSS}{_grade_css()}</style>\n</head>\n<body>\n"
            + "\n".join(body) + f"\n<script>{SCRIPT}</script>\n</body>\n</html>\n")


def _contents(toc: list[tuple[int, str, str]]) -> str:
    """The table of contents: every level-2 section, the cases nested under theirs."""
    out, nested = ['<nav id="contents"><strong>Contents</strong><ul>'], False
    for level, anchor, text in toc:
        if level == 3 and not nested:
            out[-1] = out[-1].removesuffix("</li>")
            out.append("<ul>")
            nested = True
        elif level == 2 and nested:
            out.append("</ul></li>")
            nested = False
        out.append(f'<li><a href="#{anchor}">{_inline(text)}</a></li>')
    if nested:
        out.append("</ul></li>")
    return "\n".join(out + ["</ul></nav>"])
