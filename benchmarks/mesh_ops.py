"""stimulus_engine.geometry.mesh_ops against trimesh's own operations, in one process.

For each operation that mesh_ops implements itself, the trimesh equivalent is timed on the
same mesh and compared: median seconds of repeats, the ratio trimesh / ours, and whether the
results are identical (the largest difference for float results). Mesh: the Lee Perry-Smith
head scan (9,223 vertices, needs ../shared/data), else a procedural head.

Run: .venv/bin/python benchmarks/mesh_ops.py [--repeats 20]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import timeit
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from appeal.assets import shared_data_dir  # noqa: E402
from stimulus_engine.geometry import mesh_ops  # noqa: E402


def _mesh() -> tuple[str, np.ndarray, np.ndarray]:
    d = shared_data_dir()
    path = None if d is None else d / "meshes" / "leeperrysmith" / "LeePerrySmith.obj"
    if path is not None and path.exists():
        from stimulus_engine.geometry.mesh_io import load_mesh

        m = load_mesh(path)
        return path.name, np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    from stimulus_engine.characters.procedural_head import procedural_head

    rig = procedural_head()
    return "procedural head", np.asarray(rig.vertices, np.float64), np.asarray(rig.faces, np.int64)


def _time(fn, repeats: int) -> float:
    return statistics.median(timeit.repeat(fn, number=1, repeat=repeats))


def _trimesh_edge_face_counts(faces):
    edges = trimesh.geometry.faces_to_edges(faces)[np.arange(3 * len(faces)).reshape(-1, 3)[:, [1, 2, 0]].ravel()]
    _, inverse = trimesh.grouping.unique_rows(np.sort(edges, axis=1))
    return np.bincount(inverse)[inverse].reshape(-1, 3)


def _trimesh_boundary_edges(faces):
    edges = trimesh.geometry.faces_to_edges(faces)
    return edges[trimesh.grouping.group_rows(np.sort(edges, axis=1), require_count=1)]


def _same(a, b) -> str:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return f"no (shapes {a.shape} vs {b.shape})"
    if np.array_equal(a, b):
        return "identical"
    if a.dtype.kind == "f":
        return f"no (max |diff| {np.abs(a - b).max():.2e})"
    return f"no ({int((a != b).sum())} entries differ)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    args = ap.parse_args()
    name, v, f = _mesh()
    n = len(v)
    cases = [
        ("face_normals", lambda: mesh_ops.face_normals(v, f)[0],
         lambda: trimesh.triangles.normals(v[f])[0]),
        ("vertex_normals (area-weighted)", lambda: mesh_ops.vertex_normals(v, f),
         lambda: trimesh.geometry.mean_vertex_normals(n, f, np.cross(v[f][:, 1] - v[f][:, 0], v[f][:, 2] - v[f][:, 0]))),
        ("vertex_normals vs Trimesh.vertex_normals (angle-weighted)", lambda: mesh_ops.vertex_normals(v, f),
         lambda: trimesh.Trimesh(v, f, process=False).vertex_normals),
        ("edge_face_counts", lambda: mesh_ops.edge_face_counts(f), lambda: _trimesh_edge_face_counts(f)),
        ("boundary edges (count)", lambda: len(mesh_ops.boundary_half_edges(f)),
         lambda: len(_trimesh_boundary_edges(f))),
        ("vertex_faces", lambda: mesh_ops.vertex_faces(f, n),
         lambda: np.sort(trimesh.geometry.vertex_face_indices(n, f, trimesh.geometry.index_sparse(n, f)), axis=1)),
    ]
    print(f"{name}: {n} vertices, {len(f)} faces; median of {args.repeats} repeats")
    print(f"{'operation':58s} {'ours ms':>8s} {'trimesh ms':>10s} {'ratio':>6s}  same result")
    for label, ours, theirs in cases:
        t_o, t_t = _time(ours, args.repeats), _time(theirs, args.repeats)
        a, b = ours(), theirs()
        if label == "vertex_faces":  # same sets per vertex; padding first after sorting
            a = np.sort(a, axis=1)
        print(f"{label:58s} {1e3 * t_o:8.3f} {1e3 * t_t:10.3f} {t_t / t_o:6.2f}  {_same(a, b)}")


if __name__ == "__main__":
    main()
