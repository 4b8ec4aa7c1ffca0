"""report.md's sections are registered plug-ins (harness.report.sections), shown in their declared order: a section
added by a test lands where its order puts it, and every other section renders as it did; a distribution's sections are
discovered through the entry-point group stereodyn.report_sections."""
import re
import shutil
import subprocess
import sys

import pandas as pd
import plugin_packages
import pytest

from stereodyn.harness import cli
from stereodyn.harness.report import build, sections

BUILT_IN = ["title", "verdicts", "summary", "work-precision", "cross-engine-agreement", "each-integrator", "runs-that-did-not-complete",
            "formulations-side-by-side", "cases", "oracle-and-theory-checks", "definitions", "history", "environment"]


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("sections")
    assert cli.main(["run", "lagrange-top", "--engines", "reference", "--integrators", "rk4", "--t-end", "0.5",
                     "--dt", "0.05,0.025", "--no-certify", "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    return out


def _page(out) -> str:
    markdown, _ = build.write_reports(out)
    return re.sub(r"- report rendered: .*", "", markdown.read_text())  # the one line that changes between renders


def test_the_built_in_sections_in_their_order():
    assert [s.name for s in sections.registered()] == BUILT_IN
    orders = [s.order for s in sections.registered()]
    assert orders == sorted(orders)


@pytest.mark.slow  # since 2026-12-02, ~15 s; by default the broken-section and plug-in fault tests render with a registered section (the default suite's 8 minutes)
def test_a_registered_section_lands_at_its_order_and_leaves_the_others_alone(folder):
    before = _page(folder)

    @sections.register("test-section", 65)  # between "Formulations side by side" (60) and "Cases" (70)
    def _mine(context):
        ok = int((context.results["status"] == "ok").sum())
        return ["## Test section", "", f"{ok} ok runs in {context.out_dir.name}.", ""]

    try:
        names = [s.name for s in sections.registered()]
        assert names.index("formulations-side-by-side") < names.index("test-section") < names.index("cases")
        after = _page(folder)
    finally:
        sections.unregister("test-section")
    ok = int((pd.read_csv(folder / "results.csv")["status"] == "ok").sum())
    assert ok >= 5  # the truth, and rk4 at two steps at least
    added = f"## Test section\n\n{ok} ok runs in {folder.name}.\n\n"
    assert added in after
    assert after.index(added) < after.index("## Cases\n") and after.index("## Summary\n") < after.index(added)
    assert after.replace(added, "") == before  # every other section as it was
    assert 'id="test-section"' in (folder / "report.html").read_text()
    assert _page(folder) == before  # unregistered: gone again


@pytest.mark.slow  # since 2026-12-02, ~16 s; by default the other section tests render beside it (the default suite's 8 minutes)
def test_a_section_with_nothing_to_say_is_left_out(folder):
    before = _page(folder)
    sections.register("empty", 1)(lambda context: [])
    try:
        assert _page(folder) == before
    finally:
        sections.unregister("empty")


PLUGIN = "stereodyn_test_section"
PLUGIN_MODULE = '''
from stereodyn.harness.report import sections


@sections.register("plug-in-section", 95)  # between Definitions (90) and Environment (100)
def _section(context):
    return ["## A plug-in's section", "", f"{len(context.results)} rows.", ""]
'''


def _installed(tmp_path, module: str):
    site = plugin_packages.install(tmp_path / "plugin", {
        "pyproject.toml": plugin_packages.pyproject(PLUGIN, {sections.ENTRY_POINT_GROUP: {"mine": PLUGIN}}),
        f"{PLUGIN}/__init__.py": module})
    return plugin_packages.env_with(site)


@pytest.mark.slow  # since 2026-12-02, ~9 s; likewise (the default suite's 8 minutes)
def test_a_distributions_section_is_discovered_through_its_entry_point(folder, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)
    result = subprocess.run([sys.executable, "-m", "stereodyn", "report", str(copy)], capture_output=True, text=True,
                            env=_installed(tmp_path, PLUGIN_MODULE), cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    text = (copy / "report.md").read_text()
    rows = len(pd.read_csv(copy / "results.csv"))
    assert f"## A plug-in's section\n\n{rows} rows.\n" in text
    assert text.index("## Definitions") < text.index("## A plug-in's section") < text.index("## Environment")


def test_a_broken_section_plugin_is_one_line_naming_it_and_the_report_renders(folder, tmp_path):
    """A section plug-in that raises at import is one warning line naming it (issue 29: it was exit 2, no report);
    every other section renders as before."""
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)
    result = subprocess.run([sys.executable, "-m", "stereodyn", "report", str(copy)], capture_output=True, text=True,
                            env=_installed(tmp_path, "raise RuntimeError('broken on purpose')\n"), cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stderr.strip() == (f"stereodyn: warning: report section plug-in 'mine' ({PLUGIN}, distribution "
                                     f"{PLUGIN.replace('_', '-')} 0.1.0) does not load: RuntimeError: broken on "
                                     "purpose")
    text = (copy / "report.md").read_text()
    assert all(heading in text for heading in ("# stereodyn report", "## Cases", "## Definitions", "## Environment"))
