"""``appeal validate`` checks the inputs a study file needs, not just its schema."""

from __future__ import annotations

import yaml

from appeal.assets import protocols_dir
from appeal_cli import main


def _protocol(tmp_path, stimuli: dict) -> str:
    data = yaml.safe_load((protocols_dir() / "exp2_stylisation.yaml").read_text())
    data["stimuli"] = {**stimuli, "factors": ["character", "shape", "material", "expression"]}
    data.pop("anchors", None)
    data.pop("end_of_session", None)
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump(data, allow_unicode=True))
    return str(p)


def test_missing_stimulus_folder_is_reported(tmp_path, capsys):
    p = _protocol(tmp_path, {"folder": "faces", "table": "faces/factors.csv"})
    assert main(["validate", p]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{p}: stimuli.folder: folder not found: {tmp_path / 'faces'}"]
    assert main(["validate", "--schema-only", p]) == 0


def test_missing_manifest_names_the_grid_command(capsys):
    f = protocols_dir() / "exp2_stylisation.yaml"
    if (protocols_dir().parent / "stimuli" / "exp2" / "manifest.csv").exists():
        return  # rendered in this checkout: nothing is missing
    assert main(["validate", str(f)]) == 2
    err = capsys.readouterr().err
    assert "stimuli.manifest: file not found" in err and "appeal stimuli grid" in err


def test_existing_stimuli_validate(tmp_path, capsys):
    from experiments.drawn_faces import draw_face_grid

    levels = {"character": ["c1"], "shape": [0, 1], "material": [0], "expression": ["neutral"]}
    manifest = draw_face_grid(tmp_path / "faces", levels, size=(64, 48))
    p = _protocol(tmp_path, {"manifest": str(manifest)})
    assert main(["validate", p]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out.strip() == f"{p}: ok (protocol)"
    (tmp_path / "faces" / next(iter(sorted((tmp_path / "faces").glob("*.png")))).name).unlink()
    assert main(["validate", p]) == 2
    assert "not found" in capsys.readouterr().err


def test_erp_recordings_matching_nothing_are_reported(tmp_path, capsys, shared_data):
    f = tmp_path / "erp.yaml"
    f.write_text("kind: erp\nrecordings: data/sub-*_eeg.bdf\nevents: {255: {condition: trigger}}\n")
    assert main(["validate", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{f}: recordings: pattern {tmp_path / 'data' / 'sub-*_eeg.bdf'} matches no file "
                   "(expected a glob of BDF/EDF/FIF/BrainVision/EEGLAB files or a BIDS root)"]
    assert main(["validate", "--schema-only", str(f)]) == 0
    # a list: each entry that finds nothing is named; an empty BIDS root too
    (tmp_path / "bids").mkdir()
    real = shared_data / "eeg/biosemi/Newtest17-256.bdf"
    f.write_text(f"kind: erp\nrecordings: [{real}, missing.bdf, bids]\nevents: {{255: {{condition: trigger}}}}\n")
    assert main(["validate", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert [line.split(" (")[0] for line in err] == [
        f"{f}: recordings[1]: pattern {tmp_path / 'missing.bdf'} matches no file",
        f"{f}: recordings[2]: folder {tmp_path / 'bids'} holds no *_eeg.* recordings"]
    f.write_text(f"kind: erp\nrecordings: {real}\nevents: {{255: {{condition: trigger}}}}\n")
    assert main(["validate", str(f)]) == 0
    assert capsys.readouterr().out.strip() == f"{f}: ok (erp)"
