"""out/ explains itself (issue 32): DIR/README.md lists every file and folder of a run's output, and the figures are
named by case and kind."""
import shutil
from pathlib import Path

import pytest

from stereodyn.harness import cli
from stereodyn.harness.report import index
from stereodyn.harness.report.build import figure_stem


@pytest.fixture(scope="module")
def out(tmp_path_factory) -> Path:
    # one case, one engine, one integrator, two dt, figures drawn: ~6 s of CPU measured (most of it the truth)
    out = tmp_path_factory.mktemp("index")
    assert cli.main(["run", "lagrange-top", "--engines", "mujoco", "--integrators", "rk4", "--t-end", "1",
                     "--dt", "1e-2,5e-3", "--no-ladder", "--figures", "--jobs", "1", "--quiet",
                     "--out", str(out)]) == 0
    return out


def _listed(out: Path) -> dict[str, str]:
    """{name: description} of the index's bullet lines."""
    text = (out / index.INDEX_FILE).read_text(encoding="utf-8")
    return {line[3:].split("`", 1)[0]: line.split("`: ", 1)[1]
            for line in text.splitlines() if line.startswith("- `")}


def test_every_file_of_the_output_folder_is_in_its_index_and_described(out):
    present = {f"{p.name}/" if p.is_dir() else p.name for p in out.iterdir() if not p.name.startswith(".")}
    listed = _listed(out)
    assert {"results.csv", "answers.csv", "pareto.csv", "report.html", "figures/", "store/", "runs.json",
            "README.md"} <= present
    assert set(listed) == present
    assert not [name for name, text in listed.items() if text.startswith(index.OTHER)], listed


def test_figures_are_named_by_case_and_kind(out):
    assert sorted(p.name for p in (out / "figures").iterdir()) == [
        "lagrange-top-invariants.png", "lagrange-top-work-precision.png"]
    assert "(figures/lagrange-top-invariants.png)" in (out / "report.md").read_text(encoding="utf-8")


def test_names_that_are_not_slugs_keep_a_hash():
    # "Top" and "top" would share one file by the slug alone; a non-ASCII name slugs to nothing
    assert figure_stem("top") == "top"
    assert len({figure_stem("Top"), figure_stem("top")}) == 2 and figure_stem("Top").startswith("top-")
    assert figure_stem("тело").isascii() and len(figure_stem("x" * 200)) <= 49


def test_a_foreign_file_is_listed_and_a_foreign_readme_is_kept(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    assert index.write(tmp_path) == tmp_path / "README.md"
    assert _listed(tmp_path) == {"notes.txt": index.OTHER, "README.md": index.ENTRIES["README.md"]}
    (tmp_path / "README.md").write_text("# my project\n")  # e.g. --out . in someone's repository
    assert index.write(tmp_path) is None
    assert (tmp_path / "README.md").read_text() == "# my project\n"


def test_compare_into_a_result_folder_keeps_its_index_complete(out, tmp_path):
    b = tmp_path / "b"
    shutil.copytree(out, b)
    assert cli.main(["compare", str(out), str(b), "--format", "pr"]) == 0
    present = {f"{p.name}/" if p.is_dir() else p.name for p in b.iterdir() if not p.name.startswith(".")}
    assert {"compare.md", "compare.html", "compare.csv", "compare-pr.md"} <= present
    assert set(_listed(b)) == present


def test_the_run_writes_the_answers_the_report_shows(out):
    """answers.csv (issue 47): written by the run, every digit of the table the pareto.csv, advice.csv and verdicts.csv
    make, and the report's What to use is rendered from it: a cell of the file changed by hand shows in a
    re-rendered report."""
    import pandas as pd

    from stereodyn.harness.analysis import answers

    written = pd.read_csv(out / answers.ANSWERS_FILE, keep_default_na=False, na_values=[""])
    assert tuple(written.columns) == answers.ANSWER_COLUMNS and len(written) > 0
    pd.testing.assert_frame_equal(answers.read(out), answers.compute(out), check_dtype=False)
    row = written.index[(written["scope"] == "any") & (written["engine"] != "")][0]
    written.loc[row, "dt"] = 0.0123  # not a dt of this run: only the file can put it on the page
    written.to_csv(out / answers.ANSWERS_FILE, index=False, float_format="%.17g")
    assert cli.main(["report", str(out), "--no-figures"]) == 0
    assert "dt=0.0123" in (out / "report.md").read_text(encoding="utf-8").split("## What to use")[1]


def test_a_new_render_removes_only_the_reports_own_figures(out, tmp_path):
    """`run --out .` in a folder whose figures/ held a user's plot.png deleted it (issue 46's second attack, B7): a
    render removes or replaces only CASE-KIND.png names it writes; a user's PNG, compare's and history's stay.
    Break-checked: with every *.png counted stale, plot.png and history-steps.png are deleted."""
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    mine = {"plot.png": b"mine", "history-steps.png": b"history's", "compare-largest-changes.png": b"compare's"}
    for name, data in mine.items():
        (copy / "figures" / name).write_bytes(data)
    (copy / "figures" / "gone-case-invariants.png").write_bytes(b"a figure of a case no longer in results.csv")
    assert cli.main(["report", str(copy), "--no-figures"]) == 0
    assert {p.name: p.read_bytes() for p in (copy / "figures").iterdir()} == mine
