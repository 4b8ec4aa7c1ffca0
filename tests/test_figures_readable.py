"""Figures a reader can read at 100% (issue 21 item 5): every figure of report.html, as Chromium lays the page out in a
1400 px wide window, shows its smallest text at >= 10 px, and every raster figure is drawn at >= 96 dpi.

The text height is computed, not guessed: each PNG carries its resolution (pHYs) and the smallest font size drawn in
it (harness.report.figures.FONT_KEY; a mathtext exponent counts at its drawn size, 0.7 of its label's: issue 32);
Chromium gives the width it displays the image at. Skipped without chromium
(`apt-get install -y chromium`).
"""
import base64
import io
import json
import re
import shutil
import subprocess

import pytest
from PIL import Image

from stereodyn.harness import cli
from stereodyn.harness.report import figures

# -m slow since 2026-12-02: the module's report, drawn with figures, is ~45 s on 2 idle cores (the default suite's 8
# minutes); by default tests/test_figure_layout.py checks the figures' text sizes as drawn
pytestmark = pytest.mark.slow
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
WINDOW = (1400, 2000)
MIN_TEXT_PX = 10.0
MIN_DPI = 96
MAX_HTML_BYTES = 3_000_000

# Opens every case's <details> (a closed one lays its figures out at width 0), then writes each image's displayed
# and natural widths into the page for --dump-dom.
MEASURE = """<script>window.addEventListener('load', () => {
  document.querySelectorAll('details').forEach(d => { d.open = true; });
  const sizes = [...document.images].map(i => [i.getAttribute('src').slice(0, 80), i.getBoundingClientRect().width,
                                               i.naturalWidth]);
  const pre = document.createElement('pre'); pre.id = 'measured'; pre.textContent = JSON.stringify(sizes);
  document.body.appendChild(pre); });</script>"""


def displayed_widths(page, tmp_path) -> list:
    probe = page.parent / f"probe-{tmp_path.name}.html"  # beside the report: figures/NAME.png resolve
    # every image loaded before the load event (a lazy one below the fold would have no natural size yet); its
    # displayed width is the same either way (width and height attributes)
    text = page.read_text(encoding="utf-8").replace(' loading="lazy"', "")
    probe.write_text(text.replace("</body>", MEASURE + "</body>"), encoding="utf-8")
    dom = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
                          f"--window-size={WINDOW[0]},{WINDOW[1]}", "--virtual-time-budget=20000", "--dump-dom",
                          probe.as_uri()], capture_output=True, text=True, timeout=120).stdout
    probe.unlink()
    found = re.search(r'<pre id="measured">([^<]*)</pre>', dom)
    assert found, dom[-2000:]
    return json.loads(found.group(1))


def png_of(page, src_start: str) -> bytes:
    """The PNG an <img> shows: decoded from its data: URL, or read from the file it links."""
    html = page.read_text(encoding="utf-8")
    if src_start.startswith("data:"):
        encoded = re.search(re.escape(src_start) + r'[^"]*', html).group(0).split(",", 1)[1]
        return base64.b64decode(encoded)
    return (page.parent / src_start).read_bytes()


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A report with every kind of figure and many panels: three engines, four reference formulations (six panels:
    a wrapped work-precision and invariants figure), the tolerance ladders (their figure) of a short --dt-ladder."""
    out = tmp_path_factory.mktemp("figures") / "out"
    assert cli.main(["run", "--figures", "free-asymmetric", "--engines", "mujoco,pinocchio,reference", "--integrators",
                     "rk4,euler,scipy_rk45,taylor", "--t-end", "1", "--dt", "1e-2,3e-3", "--dt-ladder",
                     "--ladder-max-steps", "100", "--no-certify", "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    return out


def check_page(page, tmp_path) -> list[str]:
    measured = displayed_widths(page, tmp_path)
    kinds = set()
    assert len(measured) >= 3
    for src, shown, natural in measured:
        image = Image.open(io.BytesIO(png_of(page, src)))
        dpi = image.info["dpi"][0]
        font = float(image.info[figures.FONT_KEY])
        text_px = font * dpi / 72.0 * shown / natural
        assert round(dpi) >= MIN_DPI, (src, dpi)
        assert text_px >= MIN_TEXT_PX, (src, f"{font} pt at {dpi:.0f} dpi shown {shown:.0f} of {natural} px: "
                                             f"{text_px:.1f} px")
        kinds.add("embedded" if src.startswith("data:") else
                  re.search(r"-(invariants|tolerance|work-precision)\.png$", src).group(1))
    return sorted(kinds)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (apt-get install -y chromium)")
def test_every_figure_is_readable_at_100_percent(report, tmp_path):
    page = report / "report.html"
    assert page.stat().st_size <= MAX_HTML_BYTES
    kinds = check_page(page, tmp_path)
    assert kinds == ["invariants", "tolerance", "work-precision"], kinds


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (apt-get install -y chromium)")
def test_the_self_contained_page_too(report, tmp_path):
    assert cli.main(["report", str(report), "--self-contained", "--figures"]) == 0
    page = report / "report.html"
    assert check_page(page, tmp_path) == ["embedded"]
    assert 'src="figures/' not in page.read_text(encoding="utf-8")  # nothing left to fetch


def test_figures_record_their_resolution_and_smallest_text(report):
    """Without a browser: every PNG at >= 96 dpi, its smallest text >= 10 px at its own size, and none wider than the
    page gives it (figures.MAX_WIDTH_PX), so a browser shows it at its own size."""
    pngs = sorted((report / "figures").glob("*.png"))
    assert len(pngs) >= 3
    for path in pngs:
        image = Image.open(path)
        dpi, font = image.info["dpi"][0], float(image.info[figures.FONT_KEY])
        assert round(dpi) >= MIN_DPI and font * dpi / 72.0 >= MIN_TEXT_PX, (path.name, dpi, font)
        assert image.size[0] <= figures.MAX_WIDTH_PX, (path.name, image.size)
