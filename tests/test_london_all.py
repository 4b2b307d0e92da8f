"""The whole public London set as data: ``london-frl-more`` registered beside ``london-frl``, and
the dataset group ``london-frl-all`` naming both as one image set."""

from __future__ import annotations

import pytest

from appeal.data_fetch import content_sha256
from appeal.datasets import dataset, expand_inputs, resolve_reference, resolve_references
from appeal.errors import AppealInputError
from appeal_cli import main
from stimulus_engine.morphpca.io import list_images


def test_london_frl_more_is_registered_and_verifies_against_the_shared_files(shared_data):
    ds = dataset("london-frl-more")
    assert ds.licence == "CC-BY-4.0" and "DeBruine" in ds.credit and ds.folder == "faces2d/london-frl-more"
    for f in ds.files:
        p = shared_data / ds.folder / f.path
        assert content_sha256(p, f.gzip) == f.sha256 and p.stat().st_size == f.size, f.path
        assert f.url is not None or f.docs, f.path
    names = {f.path for f in ds.files}
    assert sum(n.startswith("neutral_front/") and n.endswith(".tem") for n in names) == 57
    assert sum(n.startswith("smiling_front/") for n in names) == 57


def test_the_group_lists_87_neutral_identities_with_templates(shared_data, monkeypatch):
    monkeypatch.setenv("APPEAL_DATA", str(shared_data))
    files = list_images(["data:london-frl-all/neutral_front"])
    assert len(files) == 87 and len({f.name[:3] for f in files}) == 87
    assert all(f.with_suffix(".tem").is_file() for f in files)
    assert [f.parent for f in files] == sorted(f.parent for f in files)  # london-frl first, then the rest
    smiling = expand_inputs(["data:london-frl-all/smiling_front/*_08.jpg"])
    assert {f.name[:3] for f in smiling} == {f.name[:3] for f in files}


def test_group_references_and_patterns_fail_with_one_line(shared_data, monkeypatch):
    monkeypatch.setenv("APPEAL_DATA", str(shared_data))
    assert resolve_references("data:london-frl") == [resolve_reference("data:london-frl")]
    with pytest.raises(AppealInputError, match="london-frl-all.*group of datasets"):
        resolve_reference("data:london-frl-all/neutral_front")
    with pytest.raises(AppealInputError, match=r"data:london-frl-all/neutral_front/\*\.png: the pattern matches no"):
        expand_inputs(["data:london-frl-all/neutral_front/*.png"])
    with pytest.raises(AppealInputError, match="unknown dataset 'london-frl-none'.*london-frl-all"):
        expand_inputs(["data:london-frl-none/neutral_front"])


def test_appeal_data_path_and_verify_take_the_group(shared_data, monkeypatch, capsys):
    monkeypatch.setenv("APPEAL_DATA", str(shared_data))
    assert main(["data", "path", "london-frl-all"]) == 0
    assert capsys.readouterr().out.split() == [str(resolve_reference(f"data:{n}")) for n in ("london-frl", "london-frl-more")]
    assert main(["data", "verify", "london-frl-all"]) == 0
    out = capsys.readouterr().out
    assert "london-frl: ok (113 files)" in out and "london-frl-more: ok (174 files)" in out
    assert main(["data", "list"]) == 0 and "london-frl-all" in capsys.readouterr().out
