"""``appeal stimuli photo-character``: a character from one frontal photograph, written for inspection."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options


@stimuli.command("photo-character", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli photo-character "$(appeal data path london-frl)/neutral_front/001_03.jpg" --out f001
  appeal stimuli photo-character me.jpg --template me.tem --out me
  appeal stimuli photo-character face.png --ict data:ict-facekit --identity-model none --out quick   # 3 components
\b
In a grid file the same character is one line:
  characters:
    - {name: f001, photo: data:london-frl/neutral_front/001_03.jpg}""")
@click.argument("photo", metavar="PHOTO", type=click.Path(path_type=Path))
@click.option("--template", type=click.Path(path_type=Path), default=None, metavar="TEM",
              help="The photograph's .tem (dlib's 68 points, or the FRL 189-point template: its eyes, brows, nose "
                   "and lips replace dlib's); default: the .tem beside PHOTO if there is one, else dlib's 68 points.")
@click.option("--ict", default="data:ict-facekit", show_default=True, metavar="DIR",
              help="The ICT face kit (the model's mean face, expression shapes and first identity components).")
@click.option("--identity-model", default="data:ict-facekit-more", show_default=True, metavar="DIR",
              help="Further identity components (all 100 with the kit's three); 'none' for the kit's three only.")
@click.option("--texture-size", type=click.IntRange(256, 4096), default=2048, show_default=True,
              help="Side of the texture in the rig's UV layout.")
@click.option("--neutral", type=click.Choice(["identity", "photograph"]), default="identity", show_default=True,
              help="The character's neutral: the fitted identity alone (the photograph's residual expression, a "
                   "slight smile or parted lips, removed) or the fitted shape with the photograph's own expression "
                   "(its neutral render is the photograph).")
@out_options()
def photo_character_cmd(photo: Path, template: Path | None, ict: str, identity_model: str, texture_size: int,
                        neutral: str, out: Path, force: bool, resume: bool) -> None:
    """Fit the ICT face model to one frontal photograph and lay the photograph on it.

    \b
    The model's 100 identity components and its expression shapes are fitted, with the camera, to
    the photograph's 68 landmarks under the model's prior; the photograph is projected into the
    rig's UV layout where the face is seen, completed from the mirrored side and filled from the
    skin; the rest of the photograph (hair, ears, neck, clothes) becomes the surround drawn behind
    the head. Writes into DIR:

    \b
      NAME.obj, NAME.mtl, NAME_albedo.png   the fitted neutral with the rig's UVs and the photo texture
      NAME_surround.png                     the photograph behind the head, its face filled in
      NAME_landmarks.csv                    the 68 points, their fitted projections and residuals (px)
      NAME_fit.json                         identity and expression weights, camera, head turn, residuals
      NAME_overlay.png                      the photograph with the fitted mesh and the points

    A photograph with no face, two faces, a profile or a face under 80 px between the eyes is
    refused with one line naming the file; nothing is written then.
    """
    from appeal.datasets import resolve_reference
    from appeal.outputs import output_run
    from stimulus_engine.characters.photo_character import (
        found_template,
        photo_character,
        write_photo_character,
    )

    def folder(ref: str) -> Path:
        return Path(resolve_reference(ref)) if ref.startswith("data:") else Path(ref)

    model = None if identity_model.lower() == "none" else folder(identity_model)
    tem = template if template is not None else found_template(photo)
    pc = photo_character(photo, folder(ict), model, template=tem, texture_size=texture_size,
                         neutral=neutral)
    with output_run(out, force=force, resume=resume, inputs=[photo, *([tem] if tem else [])]) as run:
        files = write_photo_character(pc, run.out)
    fit = pc.fit
    click.echo(f"{pc.rig.name}: fitted to {len(pc.points)} points (rms {fit.rms:.1%} of the eye distance, "
               f"largest {fit.residuals.max():.1f} px; head turned {fit.camera.yaw_degrees:+.1f} deg, "
               f"tilted {fit.camera.pitch_degrees:+.1f} deg); {len(files)} files in {out}")
