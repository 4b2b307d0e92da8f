"""``appeal data``: the registry, ``data:`` references, and fetching through the real download path
from a loopback HTTP server (127.0.0.1) serving ``shared/data``."""

from __future__ import annotations

import gzip
import hashlib
import re
import shutil
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from appeal import datasets
from appeal.data_fetch import content_sha256, fetch_dataset, verify_dataset
from appeal.datasets import DataFile, dataset, dataset_names, resolve_reference
from appeal.errors import AppealInputError
from appeal_cli import main
from data_server import closed_port_url, serve
from upstream_tree import draco_glb_of_obj, pointed_at, upstream_tree, url_path

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def empty_data(tmp_path, monkeypatch) -> Path:
    """``APPEAL_DATA`` pointed at an empty folder (so ``shared/data`` is not searched)."""
    root = tmp_path / "appeal-data"
    root.mkdir()
    monkeypatch.setenv("APPEAL_DATA", str(root))
    monkeypatch.delenv("APPEAL_DATA_URL", raising=False)
    return root


def _err_lines(capsys) -> list[str]:
    return [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]


def _sums(text: str, prefix: str = "") -> dict[str, str]:
    return {prefix + p.removeprefix("./"): h for h, p in re.findall(r"^([0-9a-f]{64})  (\S+)$", text, re.M)}


def test_the_registry_matches_the_manifest_of_the_shared_data(shared_data):
    """Every registered file is in shared/data with the registered content; sha256 as in MANIFEST.md
    or the SHA256SUMS a registered folder holds for files added later."""
    manifest = _sums((shared_data / "MANIFEST.md").read_text())
    for name in dataset_names():
        folder = dataset(name).folder
        for sums in sorted((shared_data / folder).rglob("SHA256SUMS*")):
            manifest |= _sums(sums.read_text(), f"{sums.parent.relative_to(shared_data)}/")
    registered = set()
    for name in dataset_names():
        ds = dataset(name)
        assert ds.licence and ds.credit and ds.upstream and ds.description
        for f in ds.files:
            rel = f"{ds.folder}/{f.path}"
            p = shared_data / rel
            assert content_sha256(p, f.gzip) == f.sha256, rel
            assert p.stat().st_size == f.size, rel
            if not f.gzip and not rel.endswith(("/SHA256SUMS-more", "/SHA256SUMS")):
                assert manifest[rel] == f.sha256, rel
            registered.add(rel)
    assert set(manifest) <= registered  # every third-party file is registered


def test_upstream_urls_are_pinned_to_a_commit():
    for name in dataset_names():
        for f in dataset(name).files:
            if f.url is not None:
                assert re.match(r"https://raw\.githubusercontent\.com/[^/]+/[^/]+/[0-9a-f]{40}/", f.url), f.url
            # no shipped study file needs a mirror: every file has an upstream source
            assert f.upstream or f.docs, f"{name}/{f.path}"
    lps = {f.path: f for f in dataset("leeperrysmith").files}
    assert lps["LeePerrySmith.obj"].decode["from"] == "draco-glb" and lps["LeePerrySmith.obj"].url.endswith(".glb")
    assert lps["LeePerrySmith.mtl"].text is not None


def test_no_shipped_study_file_names_a_path_outside_the_repository():
    outside = []
    for f in sorted((ROOT / "protocols").rglob("*.yaml")):
        def walk(v, where=""):
            if isinstance(v, dict):
                for k, x in v.items():
                    walk(x, f"{where}.{k}")
            elif isinstance(v, list):
                for i, x in enumerate(v):
                    walk(x, f"{where}[{i}]")
            elif isinstance(v, str) and "/" in v and not v.startswith("data:") and " " not in v:
                p = (f.parent / v).resolve()
                if ROOT not in p.parents:
                    outside.append(f"{f.relative_to(ROOT)}: {where}: {v}")
        walk(yaml.safe_load(f.read_text()))
    assert not outside, outside
    assert "shared/data" not in "".join(p.read_text() for p in (ROOT / "protocols").rglob("*.yaml"))


def test_a_reference_to_a_missing_dataset_says_how_to_fetch_it(empty_data, capsys):
    with pytest.raises(AppealInputError, match=r"dataset 'ict-facekit' is not on this machine .* appeal data fetch ict-facekit"):
        resolve_reference("data:ict-facekit")
    with pytest.raises(AppealInputError, match="unknown dataset 'ict-kit'"):
        resolve_reference("data:ict-kit")
    assert resolve_reference("data:ict-facekit/x.obj", missing_ok=True) == empty_data / "meshes/ict-facekit/x.obj"
    rc = main(["validate", str(ROOT / "protocols" / "grids" / "erp_stylisation.yaml")])
    err = _err_lines(capsys)
    assert rc == 2 and any("characters[0].ict" in ln and "appeal data fetch ict-facekit" in ln for ln in err)
    assert any("appeal data fetch leeperrysmith" in ln for ln in err)


def test_fetch_verify_and_refetch_a_corrupted_file(shared_data, empty_data, capsys):
    with serve(shared_data) as (url, requests):
        assert main(["data", "fetch", "menpo3d-james", "--url", url]) == 0
        out = capsys.readouterr().out
        assert "7 files fetched" in out and "licence: BSD-3-Clause" in out and "Imperial College" in out
        folder = empty_data / "meshes" / "menpo3d-james"
        assert (folder / "james.obj").read_bytes() == (shared_data / "meshes/menpo3d-james/james.obj").read_bytes()
        assert main(["data", "path", "menpo3d-james"]) == 0 and capsys.readouterr().out.strip() == str(folder)
        assert main(["data", "verify"]) == 0 and "menpo3d-james: ok (7 files)" in capsys.readouterr().out
        # corrupt one cached file: verify names it, fetch gets that file only
        with open(folder / "james.jpg", "r+b") as f:
            f.seek(1000)
            f.write(b"\0" * 16)
        assert main(["data", "verify"]) == 2
        err = _err_lines(capsys)
        assert len(err) == 1 and "james.jpg: corrupt" in err[0] and "appeal data fetch menpo3d-james" in err[0]
        requests.clear()
        assert main(["data", "fetch", "menpo3d-james", "--url", url]) == 0
        assert [p for p, _ in requests] == ["/meshes/menpo3d-james/james.jpg"]
        assert main(["data", "verify", "menpo3d-james"]) == 0
        assert main(["data", "fetch", "menpo3d-james", "--url", url]) == 0 and "up to date" in capsys.readouterr().out


def test_an_interrupted_download_resumes_with_a_range_request(shared_data, empty_data):
    src = shared_data / "meshes/menpo3d-james/james.jpg"
    part = empty_data / "meshes/menpo3d-james/james.jpg.part"
    part.parent.mkdir(parents=True)
    half = src.stat().st_size // 2
    part.write_bytes(src.read_bytes()[:half])
    with serve(shared_data) as (url, requests):
        fetch_dataset("menpo3d-james", base_url=url)
    assert ("/meshes/menpo3d-james/james.jpg", f"bytes={half}-") in requests
    assert dict(verify_dataset("menpo3d-james"))["james.jpg"] == "ok" and not part.exists()


def test_a_corrupted_download_is_refused_and_nothing_is_left(shared_data, empty_data, tmp_path):
    mirror = tmp_path / "mirror"
    shutil.copytree(shared_data / "meshes/menpo3d-james", mirror / "meshes/menpo3d-james")
    with open(mirror / "meshes/menpo3d-james/james.obj", "ab") as f:
        f.write(b"# tampered\n")
    with serve(mirror) as (url, _), pytest.raises(AppealInputError) as exc:
        fetch_dataset("menpo3d-james", base_url=url)
    msg = str(exc.value)
    assert "\n" not in msg and "james.obj" in msg and "expected" in msg and "appeal data fetch menpo3d-james" in msg
    folder = empty_data / "meshes/menpo3d-james"
    assert not (folder / "james.obj").exists() and not list(folder.glob("*.part"))


def test_offline_is_one_line_naming_the_dataset_and_the_retry(empty_data, capsys):
    assert main(["data", "fetch", "menpo3d-james", "--url", closed_port_url()]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "menpo3d-james: cannot download LICENSE.txt from http://127.0.0.1:" in err[0]
    assert "retry: appeal data fetch menpo3d-james" in err[0]


def test_a_file_without_an_upstream_copy_needs_a_mirror(empty_data, capsys, monkeypatch):
    """A curator's file with neither an upstream URL nor registry text: one line, nothing downloaded."""
    ds = dataset("menpo3d-james")
    orphan = replace(ds, files=tuple(replace(f, url=None) if f.path == "james.obj" else f for f in ds.files))
    monkeypatch.setattr(datasets, "_registry", lambda: {"menpo3d-james": orphan})
    assert main(["data", "fetch", "menpo3d-james"]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "james.obj has no public upstream copy" in err[0] and "--url" in err[0]
    assert not any((empty_data).rglob("*"))  # nothing was downloaded


def _upstream_registry(monkeypatch, base: str, names: list[str]) -> None:
    """The registry with the datasets ``names`` whose upstream URLs point at the loopback server."""
    moved = {n: replace(dataset(n), files=tuple(pointed_at(f, base) for f in dataset(n).files)) for n in names}
    monkeypatch.setattr(datasets, "_registry", lambda: moved)


def test_every_shipped_study_file_is_fetched_from_upstream_without_a_mirror(shared_data, empty_data, tmp_path,
                                                                            monkeypatch, capsys):
    """`appeal data fetch --for` every shipped study file, from a loopback server laid out like the
    upstream repositories (raw, uncompressed; the Lee Perry-Smith OBJ as a Draco-compressed glTF):
    every file arrives with the registry's checksum, the scan's OBJ decoded byte for byte."""
    studies = sorted(str(p) for p in (ROOT / "protocols").rglob("*.yaml") if "data:" in p.read_text())
    names = ["ict-facekit", "ict-facekit-more", "menpo3d-james", "leeperrysmith", "gdquest-sophia", "biosemi-newtest17",
             "london-frl"]
    tree = upstream_tree(shared_data, tmp_path / "upstream", names)
    with serve(tree) as (url, requests):
        _upstream_registry(monkeypatch, url, names)
        assert main(["data", "fetch", *(a for s in studies for a in ("--for", s))]) == 0
    assert "leeperrysmith: 5 files fetched" in capsys.readouterr().out
    served = {p for p, _ in requests}
    assert any(p.endswith("/LeePerrySmith.glb") for p in served) and not any(p.endswith("LeePerrySmith.mtl") for p in served)
    for name in names:  # every file a study reads (a dataset's docs, the data tree's own README, stay upstream)
        docs = {f.path for f in dataset(name).files if f.docs}
        assert all(state == "ok" for path, state in verify_dataset(name) if path not in docs), name
    lps = empty_data / "meshes/leeperrysmith"
    assert (lps / "LeePerrySmith.obj").read_bytes() == (shared_data / "meshes/leeperrysmith/LeePerrySmith.obj").read_bytes()
    assert not list(empty_data.rglob("*part"))


def test_a_damaged_glb_upstream_is_refused_with_one_line_and_nothing_left(shared_data, empty_data, tmp_path,
                                                                           monkeypatch, capsys):
    """Upstream serving other bytes (a truncated GLB, a GLB of another mesh) is refused with the
    reason; nothing is left under the file's name or as a partial file; a good source then works."""
    tree = upstream_tree(shared_data, tmp_path / "upstream", ["leeperrysmith"])
    obj = next(f for f in dataset("leeperrysmith").files if f.path == "LeePerrySmith.obj")
    glb = tree / url_path(obj.url).lstrip("/")
    good = glb.read_bytes()
    folder = empty_data / "meshes/leeperrysmith"
    other = tmp_path / "other.obj"
    other.write_text((shared_data / "meshes/leeperrysmith/LeePerrySmith.obj").read_text().replace("v 1.29", "v 1.30", 1))
    with serve(tree) as (url, _):
        _upstream_registry(monkeypatch, url, ["leeperrysmith"])
        for damaged, why in ((good[:len(good) // 2], "truncated glTF binary"), (b"<html>404</html>", "not a binary glTF"),
                             (draco_glb_of_obj(other), "expected b4b39bd04123")):
            glb.write_bytes(damaged)
            assert main(["data", "fetch", "leeperrysmith"]) == 2
            err = _err_lines(capsys)
            assert len(err) == 1 and "LeePerrySmith.obj from http://127.0.0.1" in err[0] and why in err[0], err
            assert "retry: appeal data fetch leeperrysmith" in err[0]
            assert not (folder / "LeePerrySmith.obj").exists() and not [p for p in folder.iterdir() if "part" in p.name]
        glb.write_bytes(good)
        assert main(["data", "fetch", "leeperrysmith"]) == 0
    assert (folder / "LeePerrySmith.obj").read_bytes() == (shared_data / "meshes/leeperrysmith/LeePerrySmith.obj").read_bytes()


def test_an_upstream_file_served_uncompressed_is_stored_gzipped(shared_data, empty_data, tmp_path):
    """ICT serves .obj; the data tree keeps .obj.gz: the raw download is checked, then packed."""
    from appeal.data_fetch import _fetch_file

    ds = dataset("ict-facekit")
    f = next(x for x in ds.files if x.path == "identity001.obj.gz")
    raw = tmp_path / "upstream" / "identity001.obj"
    raw.parent.mkdir()
    raw.write_bytes(gzip.decompress((shared_data / ds.folder / f.path).read_bytes()))
    assert hashlib.sha256(raw.read_bytes()).hexdigest() == f.sha256
    dest = empty_data / ds.folder / f.path
    with serve(raw.parent) as (url, _):
        _fetch_file(ds, DataFile(f.path, f.sha256, f.size, f"{url}/identity001.obj", gzip=True), dest, None, None)
    assert content_sha256(dest, gz=True) == f.sha256 and dest.read_bytes()[:2] == b"\x1f\x8b"


@pytest.mark.slow
@pytest.mark.render
def test_exp2_renders_from_fetched_data_only(shared_data, empty_data, tmp_path, capsys):
    """Without shared/data (APPEAL_DATA empty) a shipped grid fails validation naming the datasets;
    after `appeal data fetch --for` from the loopback server it renders (one image per character)."""
    grid = yaml.safe_load((ROOT / "protocols/grids/exp2_stylisation.yaml").read_text())
    grid.update(shapes=[0.0], materials=["original"], expressions=["neutral"], lighting=grid["lighting"][:1],
                shading=grid["shading"][:1], render={"width": 256, "height": 192})
    grid["design"]["landmarks"] = str(ROOT / "protocols/grids" / grid["design"]["landmarks"])  # the copy lives elsewhere
    small = tmp_path / "exp2_small.yaml"
    small.write_text(yaml.safe_dump(grid))
    assert main(["validate", str(small)]) == 2 and "appeal data fetch" in capsys.readouterr().err
    with serve(shared_data) as (url, _):
        assert main(["data", "fetch", "--for", str(ROOT / "protocols/grids/exp2_stylisation.yaml"), "--url", url]) == 0
    fetched = {p.name for p in (empty_data / "meshes").iterdir()}
    assert fetched == {"ict-facekit", "ict-facekit-more", "gdquest-sophia"}
    assert {p.name for p in (empty_data / "faces2d").iterdir()} == {"london-frl"}  # the two photographed people
    assert main(["stimuli", "grid", str(small), "--out", str(tmp_path / "out")]) == 0
    assert len(list((tmp_path / "out" / "images").glob("*.png"))) == 2
