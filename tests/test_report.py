"""report.md and report.html: every section, self-contained HTML, every figure a real image."""
import base64
import io
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib import image as mpimg

from stereodyn.harness import cli
from stereodyn.harness.report import build
from stereodyn.harness.report.html import render

SECTIONS = {"summary": "## Summary", "each-integrator-your-method": "## Each integrator (your method)",
            "runs-that-did-not-complete": "## Runs that did not complete", "cases": "## Cases",
            "oracle-and-theory-checks": "## Oracle and theory checks", "environment": "## Environment"}
CASES = ("lagrange-top", "heavy-asymmetric")
CHECKS = pd.DataFrame([
    {"case": "lagrange-top", "engine": "reference", "formulation": "quaternion", "integrator": "taylor", "dt": None,
     "quantity": "precession_rate", "theory": 0.6541, "measured": 0.6541000001, "error": 1.5e-10},
    {"case": "lagrange-top", "engine": "mujoco", "formulation": "", "integrator": "rk4", "dt": None,
     "quantity": "convergence_order", "theory": 4.0, "measured": 3.98, "error": 5e-3}])


class Page(HTMLParser):
    """What a test needs of the page: section ids, images, styled cells, and anything that would load from outside."""

    def __init__(self):
        super().__init__()
        self.sections, self.images, self.external, self.graded, self.tags = [], [], [], 0, set()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.add(tag)
        if tag == "section":
            self.sections.append(attrs.get("id"))
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        for name in ("src", "href"):
            if name in attrs and not attrs[name].startswith(("data:", "#")):
                self.external.append(attrs[name])
        if tag == "td" and re.fullmatch(r"g\d+|s-\w+", attrs.get("class") or ""):
            self.graded += 1


@pytest.fixture(scope="module")
def reported(tmp_path_factory):
    """A sweep with a diverged run (heavy-asymmetric, Euler at dt = 0.3), then checks.csv, then `report`."""
    out = tmp_path_factory.mktemp("report")
    assert cli.main(["run", "--figures", *CASES, "--engines", "mujoco,pinocchio", "--integrators", "euler,rk4", "--t-end", "20",
                     "--dt", "0.3,1e-2", "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    assert (out / "report.md").is_file() and (out / "report.html").is_file()  # run writes both
    CHECKS.to_csv(out / "checks.csv", index=False)
    # the one-file page (report.html links figures/ by default; tests/test_figures_readable.py checks that page)
    assert cli.main(["report", str(out), "--self-contained", "--figures"]) == 0
    return out


def test_report_md_has_every_section(reported):
    text = (reported / "report.md").read_text()
    positions = [text.index(heading + "\n") for heading in SECTIONS.values()]
    assert positions == sorted(positions)  # in this order; the environment is the footer
    assert "diverged at t = " in text
    for case in CASES:
        assert f"![{case}: work–precision](figures/{build.figure_stem(case)}-work-precision.png)" in text
        assert f"![{case}: invariants](figures/{build.figure_stem(case)}-invariants.png)" in text
    assert "precession_rate" in text and "convergence_order" in text
    footer = text.split("## Environment")[1]
    for key in ("python", "numpy", "scipy", "mujoco", "pin", "heyoka", "cpu", "date", "git commit"):
        assert f"- {key}: " in footer


def test_report_html_is_self_contained_with_every_section(reported):
    page = Page()
    text = (reported / "report.html").read_text()
    page.feed(text)
    assert set(SECTIONS) <= set(page.sections)
    assert page.external == [] and not {"link", "iframe"} & page.tags  # the one script is inline
    assert len(page.images) == 2 * len(CASES)
    assert page.graded > 50  # drift and error cells and statuses carry colours
    # (a name in a cell may break after its underscores: precession_<wbr>rate)
    assert "precession_rate" in text.replace("<wbr>", "") and "git commit" in text


def test_every_figure_is_a_non_empty_image(reported):
    page = Page()
    page.feed((reported / "report.html").read_text())
    for src in page.images:
        assert src.startswith("data:image/png;base64,")
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        pixels = mpimg.imread(io.BytesIO(png), format="png")
        assert pixels.shape[0] > 100 and pixels.shape[1] > 100
        assert pixels[..., :3].std() > 0.05  # not a blank canvas: lines, labels and legends
    assert sorted(p.name for p in (reported / "figures").glob("*.png")) == sorted(
        f"{build.figure_stem(case)}-{kind}.png" for case in CASES for kind in ("invariants", "work-precision"))


@pytest.mark.slow  # since 2026-12-02, ~10 s; by default test_report_md_has_every_section (the default suite's 8 minutes)
def test_a_results_table_alone_still_gives_every_section(reported, tmp_path):
    shutil.copy(reported / "results.csv", tmp_path / "results.csv")
    assert cli.main(["report", str(tmp_path), "--figures"]) == 0
    text = (tmp_path / "report.md").read_text()
    assert all(heading + "\n" in text for heading in SECTIONS.values())
    assert "No invariants figure: no stored series in this folder" in text and "No checks.csv" in text


def test_one_case_is_counted_in_the_singular(reported, tmp_path):
    """'31 runs over 1 cases' in a one-case report (seen in a browser): the counts read as words do."""
    results = pd.read_csv(reported / "results.csv")
    case = results["case"].iloc[0]
    results[results["case"] == case].to_csv(tmp_path / "results.csv", index=False)
    pareto = pd.read_csv(reported / "pareto.csv")
    pareto[pareto["case"] == case].to_csv(tmp_path / "pareto.csv", index=False)  # What to use's tables
    assert cli.main(["report", str(tmp_path), "--no-figures"]) == 0
    text = (tmp_path / "report.md").read_text()
    assert re.search(r"\n\d+ runs over 1 case: ", text) and "1 case × " in text and "1 cases" not in text


@pytest.mark.slow  # since 2026-12-02, ~13 s; likewise (the default suite's 8 minutes)
def test_figures_drawn_in_parallel_are_the_same(reported, tmp_path, monkeypatch):
    shutil.copytree(reported, tmp_path / "copy")
    monkeypatch.setattr(build, "PARALLEL_FIGURES", 1)  # 4 figures: two processes
    build.write_reports(tmp_path / "copy")
    for png in (reported / "figures").glob("*.png"):
        assert (tmp_path / "copy" / "figures" / png.name).read_bytes() == png.read_bytes()


@pytest.mark.slow  # since 2026-12-02, ~14 s; by default the figures drawn on a worker that dies (the default suite's 8 minutes)
def test_figures_drawn_on_the_runs_worker_pool_are_the_same_and_start_no_process(reported, tmp_path, monkeypatch):
    """`stereodyn run` hands the report its worker pool's map (pipeline.phases): the figures are drawn there, by
    processes that have imported most of what drawing needs, and the report spawns none of its own."""
    from stereodyn.harness.run.pool import local_pool

    def no_processes_of_its_own(*args, **kwargs):
        raise AssertionError("the report started processes of its own")

    shutil.copytree(reported, tmp_path / "copy")
    monkeypatch.setattr(build, "ProcessPoolExecutor", no_processes_of_its_own)
    monkeypatch.setattr(build, "PARALLEL_FIGURES", 1)  # 4 figures: processes of its own without the pool's map
    drawn = []
    with local_pool(2, 5) as pool:
        def pool_map(fn, tasks):
            drawn.extend(task[:2] for task in tasks)
            return pool.map(fn, tasks)

        build.write_reports(tmp_path / "copy", render_map=pool_map)
    assert sorted(drawn) == sorted((kind, case) for case in CASES for kind in ("work-precision", "invariants"))
    for png in (reported / "figures").glob("*.png"):
        assert (tmp_path / "copy" / "figures" / png.name).read_bytes() == png.read_bytes()


def test_a_worker_that_dies_drawing_the_figures_loses_no_figure(reported, tmp_path, capsys):
    """The run's pool map raising WorkerDied (a worker killed under a figure) leaves the report whole: the figures
    are drawn in this process instead, the same, and one warning line says so (it ended `stereodyn run` with a
    traceback and no report.md)."""
    from stereodyn.harness.run.workers import WorkerDied

    def dying_map(fn, tasks):
        raise WorkerDied("worker process died (exit code -9)")

    shutil.copytree(reported, tmp_path / "copy")
    (tmp_path / "copy" / "report.md").unlink()
    build.write_reports(tmp_path / "copy", render_map=dying_map)
    warned = [line for line in capsys.readouterr().err.splitlines() if "drawing the figures" in line]
    assert warned == ["stereodyn: warning: a worker drawing the figures failed (WorkerDied: worker process died "
                      "(exit code -9)); drawing them in this process"]
    assert (tmp_path / "copy" / "report.md").exists()
    for png in (reported / "figures").glob("*.png"):
        assert (tmp_path / "copy" / "figures" / png.name).read_bytes() == png.read_bytes()


def test_our_own_bug_in_a_figure_is_raised_not_drawn_around(reported, tmp_path):
    """A bug of ours in drawing (a TypeError in build._render: harness.errors' internal error) is not data: it fails
    loudly, with no quiet redraw."""
    from stereodyn.harness.errors import InternalError

    def buggy_map(fn, tasks):
        return [fn(None) for _ in tasks]  # _render unpacks None: TypeError in our own code

    shutil.copytree(reported, tmp_path / "copy")
    with pytest.raises(InternalError, match="TypeError"):
        build.write_reports(tmp_path / "copy", render_map=buggy_map)


@pytest.mark.slow  # since 2026-12-02, ~17 s; by default every report test runs without figures (the default suite's 8 minutes)
def test_no_figures_writes_the_tables_and_says_where_the_figures_are(reported, tmp_path, monkeypatch):
    """--no-figures (and STEREODYN_FIGURES=0, tests/conftest.py) draws nothing, removes the figures of an earlier
    render and says so in each case's section; --figures draws them again."""
    shutil.copytree(reported, tmp_path / "copy")
    assert cli.main(["report", str(tmp_path / "copy"), "--no-figures"]) == 0
    text = (tmp_path / "copy" / "report.md").read_text()
    assert not list((tmp_path / "copy" / "figures").glob("*.png")) and ".png" not in text
    assert text.count(build.NOT_DRAWN) == len(CASES) and "| engine |" in text
    monkeypatch.delenv("STEREODYN_FIGURES")
    assert cli.main(["report", str(tmp_path / "copy")]) == 0  # the default without the variable: figures
    assert len(list((tmp_path / "copy" / "figures").glob("*.png"))) == 2 * len(CASES)
    assert build.NOT_DRAWN not in (tmp_path / "copy" / "report.md").read_text()


def test_markdown_subset_rendering():
    page = render("# T\n\n## A b\n\ntext `x<y`\n\n| status | energy | message |\n|---|---|---|\n"
                  "| ok | 1.00e-03 | a \\| b |\n\n- one\n  more\n- two\n")
    assert '<section id="a-b">' in page and "<code>x&lt;y</code>" in page
    assert '<td class="s-ok">ok</td>' in page and "td.s-ok { background: #d9f2d9; }" in page
    assert '<td class="g26">1.00e-03</td>' in page  # 1e-3: 13 decades above 1e-16, two classes a decade
    assert "<td class=\"t\">a | b</td>" in page and "<li>one more</li><li>two</li>" in page


def test_bold_renders_bold_in_cells_and_text_but_not_in_code():
    """What to use's cells say '**tie** with N', the verdicts' '**FAIL**': bold in the page, not asterisks (a1)."""
    page = render("# T\n\n## A\n\n| 1e-06 | verdict |\n|---|---|\n| mujoco rk4 dt=0.01 **tie** with 2 | **FAIL** |\n\n"
                  "a **bold** word, `x**2**y` and 2 ** 3\n")
    assert "<td class=\"t\">mujoco rk4 dt=0.01 <strong>tie</strong> with 2</td>" in page
    assert "<td class=\"t\"><strong>FAIL</strong></td>" in page
    assert "a <strong>bold</strong> word, <code>x**2**y</code> and 2 ** 3" in page
    assert "**" not in page.replace("<code>x**2**y</code>", "").replace("2 ** 3", "")


@pytest.mark.skipif(not (shutil.which("chromium") or shutil.which("chromium-browser")),
                    reason="no Chromium to render the page headless (apt-get install chromium)")
def test_chromium_renders_the_page(reported, tmp_path):
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    shot = tmp_path / "page.png"
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    "--window-size=1400,4000", f"--screenshot={shot}", (reported / "report.html").as_uri()],
                   check=True, capture_output=True, timeout=120)
    pixels = mpimg.imread(shot)
    assert pixels.shape[:2] == (4000, 1400)
    assert np.mean(pixels[..., :3] < 0.9) > 0.02  # text, tables and figures, not an empty page


def test_the_committed_default_report_is_whole():
    """reports/default holds the default suite's report (regenerate it with `stereodyn run --out DIR` and copy)."""
    folder = Path(__file__).resolve().parents[1] / "reports" / "default"
    text = (folder / "report.md").read_text()
    assert all(heading + "\n" in text for heading in SECTIONS.values())
    page = Page()
    page.feed((folder / "report.html").read_text())
    assert set(SECTIONS) <= set(page.sections) and page.images
    # Figures are linked from figures/ (the default since issue 21; --self-contained embeds them): every link is a
    # file of the folder, nothing loads from elsewhere.
    assert all(not re.match(r"[a-z]+:|/|\.\.", src) and (folder / src).is_file() for src in page.external), page.external
    results = pd.read_csv(folder / "results.csv")
    assert set(results.case) <= {line[4:] for line in text.splitlines() if line.startswith("### ")}
    # issue 15: under 2 MB (1.97 MB measured with the Drake and scipy rows, figures at 60 dpi), the Kovalevskaya
    # integral drawn in its case's figure
    assert (folder / "report.html").stat().st_size < 2_000_000
    kovalevskaya = text.split("### kovalevskaya\n")[1].split("\n### ")[0]
    assert "Rows of the invariants figure: energy |E−E₀|/scale; momentum drift; Kovalevskaya integral;" in kovalevskaya


def test_cost_ratios_are_the_median_over_cases_of_cheapest_against_cheapest_other_builtin():
    """report.method.cost_ratios by hand: per case the integrator's cheapest run reaching the target over the cheapest
    run of another built-in integrator reaching it (a plug-in's runs, failed runs and runs that miss the target left
    out); the median over the cases compared."""
    from stereodyn.harness.report.method import cost_ratios

    def run(case, integrator, wall_s, err, status="ok"):
        return {"case": case, "integrator": integrator, "status": status, "dt": 0.01, "t_end": 1.0,
                "attitude_err": err, "wall_s": wall_s}

    runs = pd.DataFrame([run("a", "mine", 2e-6, 1e-7), run("a", "mine", 1e-6, 1e-4),   # 1e-6: only the first
                         run("a", "rk4", 8e-6, 1e-7), run("a", "rk4", 4e-6, 1e-8),
                         run("a", "plugin", 1e-9, 1e-12),                             # not built in: no rival
                         run("b", "mine", 3e-6, 1e-8), run("b", "euler", 1e-6, 1e-7, "diverged"),
                         run("b", "euler", 6e-6, 1e-7), run("b", "rk4", 12e-6, 1e-8),  # the cheaper rival
                         run("c", "rk4", 1e-6, 1e-10)])                               # mine did not run here
    ratios = cost_ratios(runs, "mine", {"mine", "rk4", "euler"}, targets=(1e-3, 1e-6, 1e-9))
    # 1e-3: a 1e-6/4e-6, b 3e-6/6e-6 -> median of 0.25 and 0.5; 1e-6: a 2e-6/4e-6, b 0.5; 1e-9: nothing of mine
    assert ratios == {1e-3: "0.38x (2 cases)", 1e-6: "0.5x (2 cases)", 1e-9: "-"}


def test_a_runs_message_in_the_table_of_runs_that_did_not_complete_shows_as_itself():
    """Issue 46's thirteenth attack, F13: the table of runs that did not complete escaped only `|` in a run's message
    (a plug-in's text): `*x*`, `<img src=x>`, backticks and `[e](f)` rendered as markup and HTML. Escaped as every
    other value (md_text). Break-checked: without md_text the emphasis and the tag are live."""
    import pandas as pd

    from stereodyn.harness.report.markdown import problem_lines

    df = pd.DataFrame([{"case": "c", "engine": "hx", "integrator": "rk4", "formulation": "", "dt": 0.01,
                        "status": "failed", "message": "bad thing | *x* <img src=x> `y` [e](f)"}])
    row = next(line for line in problem_lines(df) if line.startswith("| failed"))
    assert r"\*x\*" in row and r"\<img src=x\>" in row and r"\`y\`" in row and r"\[e\](f)" in row and r"\|" in row, row
