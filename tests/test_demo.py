"""The demo runner: stages in order, a failing stage reported, index.html links everything."""

from __future__ import annotations

import json
import re
import shutil

import pandas as pd
import pytest

from appeal_cli import main
from appeal_cli.demo import discover_stages
from appeal.demo import DemoStage, run_demo
from appeal.report import ReportSection


def test_discovers_environment_stage():
    names = [s.name for s in discover_stages()]
    assert names[0] == "environment"


def test_run_demo_reports_failures_and_continues(tmp_path):
    def good(out, seed):
        (out / "t.csv").write_text("a\n1\n")
        return ReportSection("Good", tables=[out / "t.csv"])

    def bad(out, seed):
        raise ValueError("broken stage")

    index, sections = run_demo([DemoStage("b", "Bad", 1, bad), DemoStage("g", "Good", 2, good)], tmp_path, 0)
    assert [s.title for s in sections] == ["Bad", "Good"]
    assert sections[0].failed == "ValueError: broken stage"
    text = index.read_text()
    assert "href='g/t.csv'" in text and "broken stage" in text


def test_demo_command_environment_stage(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--only", "environment", "--seed", "3"]) == 0
    assert (out / "index.html").is_file()
    assert "environment/versions.csv" in (out / "index.html").read_text()
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["seed"] == 3 and prov["failed_stages"] == []
    assert f"Demo report: {out.resolve()}/index.html" in capsys.readouterr().out


def test_demo_unknown_stage(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--only", "nope"]) == 2
    assert "--only: unknown stage(s) nope" in capsys.readouterr().err


def test_whole_demo_every_stage_succeeds(tmp_path):
    """`appeal demo` end to end (what `make demo` runs): no stage fails, every linked file exists.

    Runs in a subprocess: the grid stage renders with pyrender and the experiment stage opens
    PsychoPy windows in its own subprocesses, as in `make demo`.
    """
    import re
    import subprocess
    import sys

    out = tmp_path / "demo"
    res = subprocess.run([sys.executable, "-m", "appeal_cli", "-q", "demo", "--out", str(out)],
                         capture_output=True, text=True, check=False, timeout=1800)
    assert res.returncode == 0, res.stderr[-2000:]
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["failed_stages"] == []
    page = (out / "index.html").read_text()
    assert "This stage failed" not in page
    names = [s.name for s in discover_stages()]
    assert {"environment", "grid", "design", "photo", "correspond", "part_morph", "avatar", "faces2d", "experiment",
            "psychophysics", "ratings", "erp", "revcorr"} <= set(names)
    links = set(re.findall(r"(?:src|href)='([^'#]+)'", page))
    assert len(links) > 20
    missing = [link for link in links if not (out / link).exists()]
    assert not missing, missing
    # the embedded real face, drawn as itself for every shape and expression
    scan = pd.read_csv(out / "grid" / "scan" / "manifest.csv")
    assert len(scan) == 36 and (scan.status == "rendered").all()  # 3 shapes x 3 measured materials x 4 expressions
    assert (out / "grid" / "scan" / "continuum.png").is_file()
    assert "grid/scan/contact_sheet_expressions.png" in links
    # its stimulus audit: the tests against the design and the grid's page that shows them
    assert {"grid/scan/audit/flags.png", "grid/scan/index.html", "grid/scan/audit/report.html"} <= links
    tests = pd.read_csv(out / "grid" / "scan" / "audit" / "design_tests.csv")
    assert {"shape", "expression"} <= set(tests["factor"]) and tests["p"].notna().any()
    # ... whose measures serve as a covariate of simulated ratings of those images: the slope is recovered
    summary = json.loads((out / "ratings" / "analysis_covariates" / "results.json").read_text())
    slope = summary["scales"]["appeal"]["lmm"]["covariates"][0]
    assert slope["term"] == "face_edge_density" and abs(slope["estimate"] - 25) < 4 * slope["se"]
    assert "ratings/scan_covariates.yaml" in links
    assert "part_morph/part_morph_sheet.png" in links  # the cartoon's eyes on the real face
    # WebMorph-style 2-D operations: a composite (its ghosting recorded) and a transform
    assert {"faces2d/composites/contact_sheet.png", "faces2d/transform/contact_sheet.png"} <= links
    comp = pd.read_csv(out / "faces2d" / "composites" / "manifest.csv")
    assert comp.loc[comp["file"] == "all_neutral.png", "ghosting"].item() < 0.4
    # psychophysics: 2AFC over a rendered continuum, a psychometric function per observer and expression
    assert {"psychophysics/analysis/figures/sub-01_psychometric.png", "psychophysics/analysis/index.html"} <= links
    pooled = pd.read_csv(out / "psychophysics" / "analysis" / "pooled.csv").set_index("expression")
    assert pooled.loc["happiness", "x_at_pc"] < pooled.loc["anger", "x_at_pc"]  # the simulated observers' order
    # the designed continuum (../shared/data here): two people's own cartoons of Sophia, eyes 2.5x or more
    assert {"design/contact_sheet.png", "design/contact_sheet_expressions.png", "design/continuum.png"} <= links
    design = pd.read_csv(out / "design" / "manifest.csv")
    assert len(design) == 36 and (design.status == "rendered").all()  # 2 people x 3 shapes x 2 materials x 3 expressions
    cont = pd.read_csv(out / "design" / "continuum.csv")
    for _, g in cont[cont["factor"] == "shape"].groupby("character"):
        g = g.sort_values("position")
        assert g["eye_area"].iloc[-1] >= 2.5 * g["eye_area"].iloc[0]
    # a character from the embedded photograph at every level, her photographs on top, her London record
    photo = pd.read_csv(out / "photo" / "manifest.csv")
    assert len(photo) == 5 * 2 * 2 + 2 and (photo.status == "rendered").all()
    assert set(photo["gender"]) == {"female"} and "photo/contact_sheet.png" in links
    # reverse correlation: simulated participants' AU models, the stylised level's jaw in happiness found
    assert {"revcorr/analysis/index.html", "revcorr/analysis/consensus_shape-stylised.png"} <= links
    changes = pd.read_csv(out / "revcorr" / "analysis" / "level_agreement.csv").fillna("")
    assert changes[changes["emotion"] == "happy"]["only_b"].str.contains("AU26").all()


def test_report_page_fits_a_laptop_screen(tmp_path):
    """Wide tables (the grid manifest has 20 columns of hashes) scroll inside their own box and
    figures scale to the page width, so the page itself never gets wider than the window."""
    import pandas as pd

    from appeal.report import ReportSection, write_index_html

    wide = tmp_path / "manifest.csv"
    pd.DataFrame({f"column_{i}": [f"{i:02d}" + "f" * 20] * 3 for i in range(20)}).to_csv(wide, index=False)
    text = "| a | b |\n|---|---|\n| 1 | 2 |\n"
    page = write_index_html(tmp_path / "index.html", "t", [ReportSection("s", text=text, tables=[wide])]).read_text()
    tables = re.findall(r"<table\b", page)
    assert len(tables) == 2
    assert len(re.findall(r"<div class='table-wrap'>\s*<table\b", page)) == 2
    style = page[page.index("<style>"):page.index("</style>")]
    assert re.search(r"\.table-wrap\{[^}]*overflow-x:auto", style)
    assert re.search(r"img\{[^}]*max-width:100%", style) and re.search(r"img\{[^}]*height:auto", style)
    assert "name='viewport'" in page


@pytest.mark.slow
def test_report_page_is_no_wider_than_a_laptop_window_in_a_browser(tmp_path):
    """Laid out by a real browser at 1366 x 768, the page with a 20-column table and a figure wider
    than the window does not scroll sideways (before: 2600 px wide)."""
    import subprocess

    import numpy as np
    import pandas as pd
    from PIL import Image

    from appeal.report import ReportSection, write_index_html

    wide = tmp_path / "manifest.csv"
    pd.DataFrame({f"column_{i}": [f"{i:02d}" + "f" * 20] * 3 for i in range(20)}).to_csv(wide, index=False)
    fig = tmp_path / "fig.png"
    Image.fromarray(np.full((300, 2400, 3), 200, np.uint8)).save(fig)
    page = write_index_html(tmp_path / "index.html", "t", [ReportSection("s", figures=[fig], tables=[wide])])
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text().replace(
        "</body>", "<script>document.body.setAttribute('data-width', document.documentElement.scrollWidth)</script></body>"))
    dom = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1366,768",
                          "--virtual-time-budget=2000", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    width = int(re.search(r'data-width="(\d+)"', dom).group(1))
    assert width <= 1366


def test_photo_stage_without_its_data_says_how_to_get_it(tmp_path, monkeypatch):
    from appeal import datasets
    from appeal_cli.demo_stages.photo import STAGE

    monkeypatch.setattr(datasets, "find_dataset", lambda name: None if name == "ict-facekit-more" else tmp_path)
    section = STAGE.run(tmp_path / "photo", 0)
    assert section.failed is None and not section.figures
    assert "appeal data fetch ict-facekit-more" in section.text
    assert not (tmp_path / "photo").exists()


def test_design_stage_without_its_data_says_how_to_get_it(tmp_path, monkeypatch):
    """The designed continuum reads registered third-party data: where it is missing, the section says
    which datasets and the command that fetches them, and nothing is rendered."""
    from appeal import datasets
    from appeal_cli.demo_stages.design import STAGE

    monkeypatch.setattr(datasets, "find_dataset", lambda name: None if name == "gdquest-sophia" else tmp_path)
    section = STAGE.run(tmp_path / "design", 0)
    assert section.failed is None and not section.figures
    assert "appeal data fetch gdquest-sophia" in section.text
    assert not (tmp_path / "design").exists()
