"""Rebuild ``appeal/assets/datasets.json``, the registry behind ``appeal data``.

For every dataset below, each file of its folder in a data tree laid out like ``shared/data``
gets its size and the sha256 of its content (of the decompressed bytes for ``.gz`` files, which
upstream serves uncompressed), and, when the same bytes are a file of a local snapshot of the
upstream git repository (matched by git blob id), the URL of that file at the snapshot's commit
on raw.githubusercontent.com. A file the curator converted is registered with how to make it
from upstream, after checking here that it makes exactly these bytes: ``decoded`` (a Draco
glTF in a snapshot, decoded by :mod:`appeal.draco_glb`) or ``written`` (a few bytes the registry
holds whole). Files without either can only be fetched from a mirror of the data tree
(``appeal data fetch --url``). A file whose content is unchanged keeps the URL the registry
already has when no snapshot given now holds it (so snapshots can be added one at a time).

Usage::

    python scripts/make_data_registry.py ../shared/data /work/.mirror

where the second folder holds one ``OWNER+REPO/repo`` bare git snapshot per upstream.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import subprocess
import sys
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "appeal" / "assets" / "datasets.json"

#: name -> folder (in the data tree), files (glob patterns in it; default all), description,
#: licence, credit, upstream (for people), files that are documentation only (not needed to run).
DATASETS: dict[str, dict] = {
    "ict-facekit": {
        "folder": "meshes/ict-facekit",
        "description": "ICT Face Model (light): neutral head, 3 identities and 33 ARKit/FACS expression "
                       "blendshapes in one topology (26,719 vertices, UVs), with its region table",
        "licence": "MIT",
        "credit": "ICT Face Model, USC Institute for Creative Technologies Vision and Graphics Lab "
                  "(Li et al. 2020, 'Learning Formation of Physically-Based Face Attributes', CVPR)",
        "upstream": "https://github.com/ICT-VGL/ICT-FaceKit (FaceXModel/)",
    },
    "menpo3d-james": {
        "folder": "meshes/menpo3d-james",
        "description": "textured 3D face scan 'james' (6,393 vertices, 2400x1600 photo texture, 68 3D landmarks)",
        "licence": "BSD-3-Clause",
        "credit": "menpo3d sample data, (c) 2014 Imperial College London and the menpo developers",
        "upstream": "https://github.com/menpo/menpo3d (menpo3d/data/)",
    },
    "leeperrysmith": {
        "folder": "meshes/leeperrysmith",
        "description": "photographic head scan of Lee Perry-Smith (9,223 vertices, 1024x1024 albedo and "
                       "normal map; eyes closed)",
        "licence": "CC-BY-3.0",
        "credit": "'Infinite, 3D Head Scan' by Lee Perry-Smith (Infinite-Realities), CC BY 3.0",
        "upstream": "three.js examples, examples/models/gltf/LeePerrySmith/ (uncompressed GLB, 396 KB); the "
                    "textures as renamed in Bruno Simon's three.js-journey course; the OBJ decoded from the "
                    "Draco-compressed copy in https://github.com/pooch1e/threeJsPortfolio (static/models/)",
        "decoded": {"LeePerrySmith.obj": {
            "repo": "pooch1e/threeJsPortfolio", "path": "static/models/LeePerrySmith/LeePerrySmith.glb",
            "decode": {"from": "draco-glb", "mtllib": "LeePerrySmith.mtl", "material": "skin",
                       "comment": "Lee Perry-Smith head scan (Infinite-Realities, CC BY 3.0), decoded from the "
                                  "three.js example glb"}}},
        "written": ["LeePerrySmith.mtl"],
    },
    "makehuman-cc0": {
        "folder": "meshes/makehuman-cc0",
        "description": "MakeHuman base mesh with CC0 eyes, eyebrows, eyelashes, eight hair styles, teeth and "
                       "tongue proxies and their .mhclo fitting files",
        "licence": "CC0-1.0",
        "credit": "MakeHuman assets, (c) 2020 Data Collection AB, Joel Palmius, Jonas Hauquier (released CC0)",
        "upstream": "https://github.com/makehumancommunity/makehuman and makehuman-assets",
        "docs": ["README.md", "proxies/MORE.md", "proxies/SHA256SUMS-more"],
    },
    "mediapipe-canonical": {
        "folder": "meshes/mediapipe-canonical",
        "description": "MediaPipe canonical face mesh (468 vertices, UVs)",
        "licence": "Apache-2.0",
        "credit": "MediaPipe, (c) Google LLC",
        "upstream": "https://github.com/google-ai-edge/mediapipe (mediapipe/modules/face_geometry/data/)",
    },
    "london-frl": {
        "folder": "faces2d/london-frl",
        "description": "Face Research Lab London Set (30 identities here): neutral photos with 189-point "
                       ".tem templates, smiling photos, composites, age/gender/ethnicity table; 1350x1350",
        "licence": "CC-BY-4.0",
        "credit": "DeBruine, L. & Jones, B. (2017). Face Research Lab London Set. figshare. "
                  "doi:10.6084/m9.figshare.5047666.v5",
        "upstream": "https://github.com/debruine/webmorphR.stim (inst/)",
    },
    "london-frl-more": {
        "folder": "faces2d/london-frl-more",
        "description": "Face Research Lab London Set, the other 57 public identities (067-173): neutral photos "
                       "with 189-point .tem templates, smiling photos; 1350x1350 (ages etc. in london-frl's table)",
        "licence": "CC-BY-4.0",
        "credit": "DeBruine, L. & Jones, B. (2017). Face Research Lab London Set. figshare. "
                  "doi:10.6084/m9.figshare.5047666.v5",
        "upstream": "https://github.com/debruine/webmorphR.stim (inst/)",
        "docs": ["README.md", "SHA256SUMS"],
    },
    "ict-facekit-more": {
        "folder": "meshes/ict-facekit-more",
        "description": "ICT Face Model (light), the rest of FaceXModel/: the other 97 identity components (100 with "
                       "ict-facekit's three) and 26 more ARKit expression shapes, same topology (gzipped); the "
                       "toolkit's own scripts",
        "licence": "MIT",
        "credit": "ICT Face Model, USC Institute for Creative Technologies Vision and Graphics Lab "
                  "(Li et al. 2020, 'Learning Formation of Physically-Based Face Attributes', CVPR)",
        "upstream": "https://github.com/ICT-VGL/ICT-FaceKit (FaceXModel/) at da5f95a607f5e6b37755b38d3385d7f2853732e5",
        "docs": ["README.md", "SHA256SUMS"],
    },
    "gdquest-sophia": {
        "folder": "meshes/gdquest-sophia",
        "description": "an artist-made stylised (chibi) character: sophia.glb (head, body and hair, painted decal "
                       "eyes and mouth, embedded textures), the eye decals' texture, GDQuest's screenshot",
        "licence": "CC-BY-4.0",
        "credit": "Additional assets CC-By 4.0 GDQuest (https://www.gdquest.com/): Sophia, from "
                  "gdquest-demos/godot-4-3D-Characters at commit 8034d3fede52 (later commits offer it under CC "
                  "BY-NC-SA 4.0; this copy is the CC BY 4.0 one)",
        "upstream": "https://github.com/gdquest-demos/godot-4-3D-Characters (src/addons/gdquest_sophia/) at "
                    "8034d3fede52c8a58d2cbc7b8d3e8e6c79f6c8b3",
        # the file URLs at the commit whose licence is CC BY 4.0, not at the snapshot's newest commit
        "pinned": {"repo": "gdquest-demos/godot-4-3D-Characters", "commit": "8034d3fede52c8a58d2cbc7b8d3e8e6c79f6c8b3"},
        "docs": ["README.md", "SHA256SUMS", "look.png", "sophia_skin.gd", "LICENSE.md"],
    },
    "biosemi-mne": {
        "folder": "eeg/biosemi",
        "files": ["test.bdf", "test_bdf_eeglab.mat", "test_bdf_stim_channel.bdf", "multiple_annotation_chans.bdf"],
        "description": "BioSemi BDF test recordings of MNE-Python (64+8 channels at 2048 Hz; 3 channels with "
                       "triggers; trigger and annotation channels) and EEGLAB's reading of test.bdf",
        "licence": "BSD-3-Clause",
        "credit": "MNE-Python and mne-testing-data, (c) the MNE-Python developers",
        "upstream": "https://github.com/mne-tools/mne-python (mne/io/edf/tests/data/), mne-tools/mne-testing-data (BDF/)",
    },
    "biosemi-newtest17": {
        "folder": "eeg/biosemi",
        "files": ["Newtest17-256.bdf"],
        "description": "BioSemi's sample recording Newtest17-256 (16 channels + Status, 256 Hz, 60 s)",
        "licence": "MIT",
        "credit": "BioSemi sample data, distributed with the eeguana R package (c) Bruno Nicenboim",
        "upstream": "https://github.com/bnicenboim/eeguana (inst/testdata/)",
    },
}


def _blob(data: bytes) -> str:
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def _snapshots(mirrors: Path) -> dict[str, str]:
    """git blob id -> raw URL of that file at the snapshot's commit."""
    index: dict[str, str] = {}
    for snap in sorted(mirrors.iterdir()):
        repo = snap / "repo"
        if not repo.exists() or "+" not in snap.name:
            continue
        owner, name = snap.name.split("+", 1)
        git = ["git", "-C", str(repo)]
        commit = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
        tree = subprocess.run([*git, "ls-tree", "-r", "HEAD"], capture_output=True, text=True, check=True).stdout
        for line in tree.splitlines():
            meta, path = line.split("\t", 1)
            index.setdefault(meta.split()[2], f"https://raw.githubusercontent.com/{owner}/{name}/{commit}/{path}")
    return index


def _pinned(mirrors: Path, repo_name: str, commit: str) -> dict[str, str]:
    """git blob id -> raw URL of that file at ``commit`` of the snapshot of ``repo_name`` (empty without it)."""
    repo = mirrors / repo_name.replace("/", "+") / "repo"
    if not repo.exists():
        return {}
    tree = subprocess.run(["git", "-C", str(repo), "ls-tree", "-r", commit], capture_output=True, text=True,
                          check=True).stdout
    return {line.split("\t", 1)[0].split()[2]: f"https://raw.githubusercontent.com/{repo_name}/{commit}/"
                                               f"{line.split(chr(9), 1)[1]}" for line in tree.splitlines()}


def _decoded_source(mirrors: Path, spec: dict, sha256: str) -> dict:
    """``url`` and ``decode`` of a converted file when the snapshot's source decodes to ``sha256``."""
    from appeal.draco_glb import ObjStyle, decode_draco_glb, obj_bytes

    repo = mirrors / spec["repo"].replace("/", "+") / "repo"
    if not repo.exists():
        return {}
    git = ["git", "-C", str(repo)]
    commit = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    glb = subprocess.run([*git, "show", f"HEAD:{spec['path']}"], capture_output=True, check=True).stdout
    style = ObjStyle(**{k: v for k, v in spec["decode"].items() if k != "from"})
    if hashlib.sha256(obj_bytes(decode_draco_glb(glb, name=spec["path"]), style)).hexdigest() != sha256:
        print(f"  {spec['repo']}/{spec['path']} does not decode to the data tree's file: not registered")
        return {}
    return {"url": f"https://raw.githubusercontent.com/{spec['repo']}/{commit}/{spec['path']}", "decode": spec["decode"]}


def _previous() -> dict[tuple[str, str], dict]:
    """(dataset, path) -> the registry's entry now."""
    if not OUT.exists():
        return {}
    return {(name, f["path"]): f for name, d in json.loads(OUT.read_text()).items() for f in d["files"]}


def main(data: Path, mirrors: Path) -> None:
    index = _snapshots(mirrors)
    before = _previous()
    out = {}
    for name, spec in DATASETS.items():
        folder = data / spec["folder"]
        own = _pinned(mirrors, spec["pinned"]["repo"], spec["pinned"]["commit"]) if "pinned" in spec else {}
        names = spec.get("files") or sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
        files = []
        for rel in names:
            raw = (folder / rel).read_bytes()
            gz = rel.endswith(".gz")
            content = gzip.decompress(raw) if gz else raw
            entry = {"path": rel, "sha256": hashlib.sha256(content).hexdigest(), "size": len(raw),
                     "url": own.get(_blob(content)) or (None if own else index.get(_blob(content)))}
            if rel in spec.get("decoded", {}):
                entry |= _decoded_source(mirrors, spec["decoded"][rel], entry["sha256"])
            if rel in spec.get("written", ()):
                entry["text"] = content.decode("utf-8")
            old = before.get((name, rel), {})
            if entry["url"] is None and "text" not in entry and old.get("sha256") == entry["sha256"]:
                entry |= {k: old[k] for k in ("url", "decode") if old.get(k) is not None}
            if gz:
                entry["gzip"] = True
            if rel in spec.get("docs", ()):
                entry["docs"] = True
            files.append(entry)
        out[name] = ({k: v for k, v in spec.items() if k not in ("files", "docs", "decoded", "written", "pinned")}
                     | {"files": files})
        n_url = sum(f["url"] is not None or "text" in f for f in files)
        print(f"{name}: {len(files)} files, {sum(f['size'] for f in files) / 1e6:.1f} MB, {n_url} from upstream")
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(OUT)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    main(Path(sys.argv[1]), Path(sys.argv[2]))
