"""``appeal stimuli rig-transfer`` and ``appeal stimuli retarget``: expressions across faces (thesis ch. 4)."""

from __future__ import annotations

from pathlib import Path

import click

from appeal.cells import write_table
from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import refuse_existing_file

_METHODS = ("aligned", "rbf", "deformation_transfer")


def _rig(ict: Path, identity: str):
    from stimulus_engine.characters.ict import load_ict_rig

    return load_ict_rig(ict, identity, textures=False)  # geometry only: nothing here is drawn


@stimuli.command("rig-transfer", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli rig-transfer --ict "$(appeal data path ict-facekit)" --shape 1.0 --out cartoon_rig.npz
  appeal stimuli rig-transfer --ict DIR --target face.obj --method rbf --out face_rig.npz
  appeal stimuli rig-transfer --ict DIR --shape 0.5 --method deformation_transfer --out dt.npz""")
@click.option("--ict", "ict", required=True, type=click.Path(path_type=Path), help="The ICT-FaceKit folder (the rig).")
@click.option("--identity", default="identity000", show_default=True, help="The rig's identity.")
@click.option("--shape", "shape", type=float, default=None,
              help="Target: the rig's own face stylised to this level (0 realistic .. 1 cartoon).")
@click.option("--target", "target", type=click.Path(path_type=Path), default=None,
              help="Target: a mesh in the rig's topology (same vertex count and order), e.g. an ElastiFace fit.")
@click.option("--method", type=click.Choice(_METHODS), default="aligned", show_default=True,
              help="aligned: E_Align, the target moves as far in units of its own face as the rig; rbf: RBF "
                   "proportion matching; deformation_transfer: Sumner & Popović.")
@click.option("--out", "out", required=True, type=click.Path(path_type=Path), help="Output .npz file.")
@click.option("--force", is_flag=True, help="Overwrite --out.")
def rig_transfer(ict: Path, identity: str, shape: float | None, target: Path | None, method: str, out: Path,
                 force: bool) -> None:
    """The rig's blendshapes carried onto a stylised level or another face in its topology.

    \b
    Writes OUT.npz: 'neutral' (the target, N x 3, cm), 'names' and 'blendshapes' (K x N x 3
    deltas, in the names' order), and 'faces'. A face posed by weights w is
    neutral + sum_k w_k blendshapes[k]. With --method aligned the target's range of motion is
    the rig's scaled by the ratio of the two faces' lengths (forehead to chin), so an
    expression moves each face equally far in units of its own size (thesis ch. 4,
    stimulus_engine.characters.blendshape_transfer).
    """
    import numpy as np

    from appeal.atomic import atomic_write_bytes
    from appeal.errors import AppealInputError
    from stimulus_engine.characters.blendshape_transfer import transfer_blendshapes

    if (shape is None) == (target is None):
        raise AppealInputError("rig-transfer: give exactly one of --shape LEVEL or --target MESH")
    refuse_existing_file(out, force)
    rig = _rig(ict, identity)
    if shape is not None:
        from stimulus_engine.stylisation.shape import stylise

        if not 0.0 <= shape <= 1.0:
            raise AppealInputError(f"--shape {shape}: expected a stylisation level within 0..1")
        neutral = stylise(rig, shape)
    else:
        from stimulus_engine.geometry.mesh_io import load_mesh

        neutral = np.asarray(load_mesh(target).vertices, np.float64)
        if neutral.shape != rig.vertices.shape:
            raise AppealInputError(f"{target}: {len(neutral)} vertices, expected {len(rig.vertices)} in the order of "
                                   f"rig '{identity}' (correspond the mesh first: appeal stimuli correspond)")
    shapes = transfer_blendshapes(rig, neutral, method)
    names = sorted(shapes)
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, neutral=neutral, names=np.array(names), faces=rig.faces,
                        blendshapes=np.stack([shapes[n] for n in names]).astype(np.float32))
    atomic_write_bytes(out, buf.getvalue())
    click.echo(f"{len(names)} blendshapes ({method}) onto {'shape ' + str(shape) if target is None else target}: {out}")


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli retarget take1.c3d --ict DIR --marker-map markers.csv --out take1_weights.csv
  appeal stimuli retarget markers.csv --ict DIR --out weights.csv        # frame,marker,x,y,z; markers v<vertex>
  appeal stimuli retarget arkit.csv --ict DIR --transfer rbf --out w.csv  # frame + blendshape columns""")
@click.argument("motion", type=click.Path(path_type=Path))
@click.option("--ict", "ict", required=True, type=click.Path(path_type=Path), help="The ICT-FaceKit folder (the rig).")
@click.option("--identity", default="identity000", show_default=True, help="The rig's identity.")
@click.option("--marker-map", "marker_map", type=click.Path(path_type=Path), default=None,
              help="CSV marker,vertex: the rig vertex under each marker label.")
@click.option("--fps", type=float, default=None, help="Frame rate of a CSV (default 30; a C3D has its own).")
@click.option("--transfer", type=click.Choice(["aligned", "rbf"]), default="aligned", show_default=True,
              help="How the actor's blendshapes are made from the rig's (aligned: to the performance's range of motion).")
@click.option("--mu", type=float, default=0.01, show_default=True,
              help="Weight of the bending prior (Eq. 4.16), relative to the fit: scale-free, whatever the markers' units.")
@click.option("--nu", type=float, default=0.2, show_default=True,
              help="Weight of the L1 sparsity (Eq. 4.16), relative to the fit (each weight lowered by about nu/2K).")
@click.option("--out", "out", required=True, type=click.Path(path_type=Path), help="Output CSV of weights.")
@click.option("--force", is_flag=True, help="Overwrite --out.")
def retarget(motion: Path, ict: Path, identity: str, marker_map: Path | None, fps: float | None, transfer: str,
             mu: float, nu: float, out: Path, force: bool) -> None:
    """A performance (MOTION: .c3d or .csv) as weights of the rig's blendshapes, frame by frame.

    \b
    Frame 0 of a marker file is the actor's neutral. The actor's blendshapes are the rig's
    aligned to the performance's range of motion (thesis §4.3), then each frame is solved by
    Eq. 4.16: fit + mu * bending prior + nu * L1 sparsity, weights >= 0 (non-negative least
    squares). mu and nu are relative to the fit (the fit divided by a blendshape's mean squared
    marker motion, the prior by its own scale), so the defaults hold for markers in mm or cm;
    the thesis's 0.3 and 0.6 assumed its own units and erase an ICT-sized performance. Where
    this departs from the thesis: stimulus_engine.characters.retarget. Writes OUT: frame,
    time (s), one column per blendshape.
    """
    import pandas as pd

    from stimulus_engine.characters.motion_files import read_motion
    from stimulus_engine.characters.retarget import retarget_performance

    refuse_existing_file(out, force)
    rig = _rig(ict, identity)
    neutral, positions, vertices, rate, _ = read_motion(motion, rig, marker_map, fps)
    w = retarget_performance(rig, neutral, positions, vertices, transfer=transfer, mu=mu, nu=nu)
    table = pd.DataFrame(w, columns=sorted(rig.blendshapes))
    table.insert(0, "time", [round(i / rate, 6) for i in range(len(w))])
    table.insert(0, "frame", range(len(w)))
    write_table(table, out, float_format="%.6f")
    click.echo(f"{len(w)} frames at {rate:g} fps, {len(vertices)} markers -> {out}")
