"""The README's tour, run as written: two participants in a row, then the rating analysis.

The tour's commands are read from README.md itself, so the test follows the README. The first
participant is a live PsychoPy session (tested with real key presses in the live-session tests);
here it gets ``--simulate default --no-window`` appended and nothing else changed. The stimuli
are small drawn faces with the protocol's own factor levels, placed where the tour's
``appeal stimuli grid ... --out stimuli/exp2`` would put them.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from appeal.assets import protocols_dir

ROOT = Path(__file__).resolve().parents[1]


def _tour_commands() -> list[list[str]]:
    """The ``appeal`` lines of the README's "A whole study" code block, comments dropped."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"A whole study.*?```bash\n(.*?)```", text, flags=re.S)
    assert block, "README.md: the tour's code block ('A whole study ... ```bash') is missing"
    return [shlex.split(line, comments=True) for line in block.group(1).splitlines() if line.startswith("appeal ")]


def _appeal(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", "appeal_cli", "-q", *argv[1:]], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600, check=False)


def test_tour_lists_two_participants_and_the_analysis():
    runs = [c for c in _tour_commands() if c[1] == "run"]
    assert len(runs) >= 2, "the tour shows two participants"
    assert {c[c.index("--participant") + 1] for c in runs} >= {"01", "02"}
    assert any(c[1:3] == ["analyze", "ratings"] for c in _tour_commands())


@pytest.mark.slow
def test_tour_runs_as_written_for_two_participants_in_a_row(tmp_path):
    from experiments.drawn_faces import draw_face_grid

    shutil.copytree(protocols_dir(), tmp_path / "protocols")
    commands = _tour_commands()
    runs = [c for c in commands if c[1] == "run" and "exp2_stylisation" in c[2]]
    protocol = yaml.safe_load((tmp_path / runs[0][2]).read_text(encoding="utf-8"))
    levels = {"character": ["c1", "c2"], **protocol["stimuli"]["levels"],
              "expression": ["neutral", "happiness"]}
    manifest = tmp_path / "protocols" / protocol["stimuli"]["manifest"]
    draw_face_grid(manifest.parent, levels, size=(80, 60))
    assert manifest.resolve().is_relative_to(tmp_path / "stimuli")

    for argv in runs:
        if "--simulate" not in argv:
            argv = [*argv, "--simulate", "default", "--no-window"]
        res = _appeal(argv, tmp_path)
        assert res.returncode == 0, f"{shlex.join(argv)} failed:\n{res.stderr}"
    for participant in ("01", "02"):
        beh = list((tmp_path / "data" / f"sub-{participant}" / "ses-1" / "beh").glob("*_beh.tsv"))
        assert len(beh) == 1, f"participant {participant}: no data file where the README says"

    analyze = next(c for c in commands if c[1:3] == ["analyze", "ratings"] and "exp2" in c[3])
    res = _appeal(analyze, tmp_path)
    assert res.returncode == 0, res.stderr
    out = tmp_path / analyze[analyze.index("--out") + 1]
    assert (out / "results.json").is_file()


def test_gitignore_covers_what_the_tour_writes():
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    paths = ["data/sub-01/ses-1/beh/sub-01_ses-1_task-exp2_beh.tsv", "stimuli/exp2/manifest.csv",
             "results/exp2/results.json", "demo_out/index.html"]
    res = subprocess.run(["git", "check-ignore", "--no-index", *paths], cwd=ROOT, capture_output=True,
                         text=True, check=False)
    assert sorted(res.stdout.split()) == sorted(paths)
