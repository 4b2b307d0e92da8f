"""``appeal stimuli morphpca …``: morph-space PCA face models (build, project, avatar, reconstruct)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from appeal.atomic import atomic_write_text
from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options
from appeal.errors import AppealInputError
from stimulus_engine.morphpca.defaults import DEFAULT_TEXTURE_WEIGHT

_JSON_HELP = "Also write the metrics (explained variance, PSNR/SSIM, seconds) to this JSON file."


@stimuli.group(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca build frames/ --keypoints keypoints.csv --out models/alice
  appeal stimuli morphpca project smile.png --from models/alice/model.npz --to models/bob/model.npz --out proj
  appeal stimuli morphpca avatar models/*/model.npz --out avatar
  appeal stimuli morphpca reconstruct avatar/model.npz --loadings proj/loadings.csv --out frames""")
def morphpca() -> None:
    """Morph-space PCA face models (Nagle et al.): expression spaces, mimicry, avatars.

    \b
    A model is built from aligned images of one person (an expression space) or of many
    people (a face space). Faces become morph vectors (texture on the mean shape + warp
    field from optical flow), compressed by PCA. Expressions can be projected from one
    person's model into another's, and several identity models blended into an avatar.
    """


def _write_metrics(run, metrics: dict, json_path: Path | None) -> None:
    text = json.dumps(metrics, indent=2, default=float) + "\n"
    atomic_write_text(run.path("metrics.json"), text)
    if json_path is not None:
        atomic_write_text(json_path, text)
    run.extra["metrics"] = metrics


@morphpca.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca build frames/ --out models/alice --components 50
  appeal stimuli morphpca build frames/*.png --keypoints keypoints.csv --out models/alice
  appeal stimuli morphpca build faces/ --keypoints tem --register --size 240x200 --out models/facespace
  appeal stimuli morphpca build photos/ --keypoints detect --register --out models/bob --json bob.json
  appeal stimuli morphpca build data:london-frl-all/neutral_front --keypoints tem --register --size 240x200 \
      --holdout-every 5 --out models/london87     # the 87 London identities, a fifth held out""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@out_options()
@click.option("--keypoints", "keypoints", default=None, metavar="FILE|tem|detect",
              help="Keypoints per image: a CSV (image,left_eye_x,left_eye_y,right_eye_x,right_eye_y,philtrum_x,"
                   "philtrum_y, optionally dense landmarks p0_x,p0_y,p1_x,...), 'tem' (the 189-point WebMorph .tem "
                   "beside each image) or 'detect' (dlib's 68 points, offline). Dense landmarks guide the warps "
                   "(see --warp).")
@click.option("--register", is_flag=True, help="Similarity-align faces on their eye centres first (needs --keypoints).")
@click.option("--size", default=None, metavar="HxW", help="Resize (or, with --register, crop) images to this size, e.g. 240x200.")
@click.option("--components", type=click.IntRange(min=1), default=None, help="Principal components to keep (default: all).")
@click.option("--variance", type=click.FloatRange(0, 1, min_open=True), default=None,
              help="Keep the fewest components explaining this fraction of variance (e.g. 0.98).")
@click.option("--reference", "reference", default="0", metavar="INDEX|NAME",
              help="Reference image (neutral, eyes open): index or file name.", show_default=True)
@click.option("--backend", type=click.Choice(["dis", "farneback"]), default="dis", show_default=True,
              help="Optical flow (the paper's McGM is not available).")
@click.option("--holdout", type=click.IntRange(min=0), default=0, show_default=True,
              help="Leave the last N images out of the model and report their reconstruction PSNR/SSIM.")
@click.option("--holdout-every", type=click.IntRange(min=2), default=None, metavar="K",
              help="Leave every K-th image out instead (5: a fifth, spread over the set).")
@click.option("--warp", type=click.Choice(["guided", "flow", "landmarks"]), default="guided", show_default=True,
              help="With dense landmarks (tem, detect, or pK_x/pK_y columns): 'guided' = a thin-plate spline through "
                   "them refined by optical flow inside the face (for faces of different people), 'flow' = optical "
                   "flow alone (frames of one person), 'landmarks' = the spline alone (Psychomorph-style).")
@click.option("--json", "json_path", type=click.Path(path_type=Path), default=None, metavar="METRICS", help=_JSON_HELP)
def build(images, out, force, resume, keypoints, register, size, components, variance, reference, backend, holdout,
          holdout_every, warp, json_path) -> None:
    """Build a PCA morph model from aligned face IMAGES (files, folders, data:NAME/sub references, patterns).

    Writes DIR/model.npz (+ model.json metadata), DIR/mean.png, DIR/components.png (the mean
    ± 2 SD along the first components), DIR/metrics.json and, with --keypoints, the faceframe.
    """
    from appeal.outputs import output_run
    from stimulus_engine.morphpca.workflow import build_morph_model, read_morph_inputs

    inputs = read_morph_inputs(images, keypoints=keypoints, register=register, size=size, reference=reference,
                               holdout=holdout, holdout_every=holdout_every or 0)  # bad input: one-line errors before any output folder is made
    with output_run(out, force=force, resume=resume, inputs=inputs.files) as run:
        model, metrics = build_morph_model(inputs, run.out, components=components, variance=variance, backend=backend,
                                           warp=warp)
        _write_metrics(run, metrics, json_path)
    click.echo(f"{run.out / 'model.npz'}: {model.n_components} components, "
               f"{100 * metrics['explained_variance']:.1f}% variance, train PSNR {metrics['train_psnr_db']:.1f} dB"
               + (f", hold-out PSNR {metrics['holdout_psnr_db']:.1f} dB (orthogonal projection "
                  f"{metrics['holdout_psnr_projection_db']:.1f} dB)" if "holdout_psnr_db" in metrics else ""))


@morphpca.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca pair neutral_front/001_03.jpg smiling_front/001_08.jpg --out models/p001
  appeal stimuli morphpca pair a_neutral.jpg a_smile.jpg --frames 16 --size 300x250 --out models/a
  appeal stimuli morphpca project models/p001/frames --keypoints models/p001/frames/keypoints.csv \\
      --from models/p001/model.npz --to models/p002/model.npz --out smile""")
@click.argument("neutral", type=click.Path(path_type=Path))
@click.argument("expressive", type=click.Path(path_type=Path))
@out_options()
@click.option("--frames", "n_frames", type=click.IntRange(min=2), default=10, show_default=True,
              help="Frames of the morph sequence that stands in for a video.")
@click.option("--size", default="240x200", show_default=True, metavar="HxW", help="Registered image size.")
@click.option("--json", "json_path", type=click.Path(path_type=Path), default=None, metavar="METRICS", help=_JSON_HELP)
def pair(neutral, expressive, out, force, resume, n_frames, size, json_path) -> None:
    """An expression space from two photographs of one person (NEUTRAL and EXPRESSIVE).

    \b
    Detects 68 landmarks in both (dlib, offline), registers them on the eyes, morphs one into
    the other (thin-plate splines + cross-dissolve) and builds a morph-PCA model from the
    frames: a stand-in for the video frames Nagle et al. model. Writes DIR/model.npz,
    DIR/mean.png, DIR/frames/frameNNN.png, DIR/frames/keypoints.csv (every frame's 68 points)
    and DIR/metrics.json; project the frames onto another person's model with 'appeal stimuli
    morphpca project DIR/frames --keypoints DIR/frames/keypoints.csv …'.
    """
    import time

    from appeal.outputs import output_run
    from stimulus_engine.morphpca.io import list_images, parse_size
    from stimulus_engine.morphpca.metrics import psnr
    from stimulus_engine.morphpca.workflow import pair_expression_model

    files = list_images([neutral, expressive])  # missing files: one line before any output
    shape = parse_size(size)
    with output_run(out, force=force, resume=resume, inputs=files) as run:
        t0 = time.perf_counter()
        model, frames, _, _ = pair_expression_model(files[0], files[1], run.out, size=shape, n_frames=n_frames)
        rec = model.reconstruct(model.loadings)
        psnrs = [psnr(a, b) for a, b in zip(rec, frames)]
        metrics = {"frames": n_frames, "n_components": model.n_components,
                   "train_psnr_db": float(sum(psnrs) / len(psnrs)),
                   "seconds": time.perf_counter() - t0}
        _write_metrics(run, metrics, json_path)
    click.echo(f"{run.out / 'model.npz'}: {n_frames} frames, {model.n_components} components")


@morphpca.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca project smile.png --from models/alice/model.npz --to models/bob/model.npz --out proj
  appeal stimuli morphpca project frames/ --from A.npz --to B.npz --out proj --caricature 1.5 --naive
  appeal stimuli morphpca project a.png --from A.npz --to B.npz --truth b.png --out proj --json m.json
  appeal stimuli morphpca project alice.mp4 --from A.npz --to B.npz --out proj      # every frame of a recording""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--from", "source", required=True, type=click.Path(path_type=Path), metavar="A.npz", help="Model of the person in IMAGES.")
@click.option("--to", "target", required=True, type=click.Path(path_type=Path), metavar="B.npz", help="Model to render the expressions on.")
@out_options()
@click.option("--no-align", is_flag=True, help="Skip the faceframe affine transform (models of equal size only).")
@click.option("--caricature", type=float, default=1.0, show_default=True, help="Scale the projected warp (1.5 = 50% stronger).")
@click.option("--texture-weight", type=click.FloatRange(min=0), default=DEFAULT_TEXTURE_WEIGHT, show_default=True,
              help="Weight of texture vs warp when fitting B's loadings (1 = the paper's inner product; 0.1 lets the warp decide).")
@click.option("--keypoints", "keypoints", default=None, metavar="FILE",
              help="The images' landmarks (a CSV with pK_x/pK_y columns, e.g. the frames/keypoints.csv of "
                   "'morphpca pair'): encode them as model A's training images were (landmark-guided).")
@click.option("--naive", is_flag=True, help="Also write the naive loading-transfer baseline.")
@click.option("--truth", "truth", multiple=True, type=click.Path(path_type=Path),
              help="True images of B with the same expressions (one per IMAGE): report SSIM/PSNR of both methods.")
@click.option("--json", "json_path", type=click.Path(path_type=Path), default=None, metavar="METRICS", help=_JSON_HELP)
def project(images, source, target, out, force, resume, no_align, caricature, texture_weight, keypoints, naive, truth,
            json_path) -> None:
    """Project the expressions of IMAGES (person A: image files, folders or video files) onto the face of model B.

    Writes DIR/projected/NAME.png (and DIR/naive/NAME.png with --naive), DIR/loadings.csv
    (loadings in B), DIR/sheet.png (inputs beside their projections) and DIR/metrics.json.
    """
    from appeal.outputs import output_run
    from stimulus_engine.morphpca.workflow import project_images, read_projection_inputs

    inputs = read_projection_inputs(images, source, target, truth, keypoints)
    with output_run(out, force=force, resume=resume, inputs=[source, target, *inputs.files]) as run:
        metrics = project_images(inputs, run.out, align=not no_align, caricature=caricature,
                                 texture_weight=texture_weight, naive=naive)
        _write_metrics(run, metrics, json_path)
    click.echo(f"{run.out / 'projected'}: {len(inputs.images)} image(s)" +
               (f"; SSIM to truth {metrics['ssim_projection']:.3f} (naive {metrics['ssim_naive']:.3f})"
                if inputs.truth is not None else ""))


@morphpca.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca avatar models/*/model.npz --out avatar
  appeal stimuli morphpca avatar a.npz b.npz c.npz --weights 0.5,0.25,0.25 --out avatar_a
  appeal stimuli morphpca avatar a.npz b.npz --reference 1 --components 20 --out avatar --json m.json""")
@click.argument("models", nargs=-1, required=True, type=click.Path(path_type=Path))
@out_options()
@click.option("--reference", type=int, default=0, show_default=True, help="Model whose faceframe the avatar uses.")
@click.option("--weights", default=None, metavar="W1,W2,...", help="Identity weights (sum 1; default equal).")
@click.option("--components", type=click.IntRange(min=1), default=None, help="Components of the avatar model.")
@click.option("--texture-weight", type=click.FloatRange(min=0), default=DEFAULT_TEXTURE_WEIGHT, show_default=True,
              help="See 'project --help'.")
@click.option("--json", "json_path", type=click.Path(path_type=Path), default=None, metavar="METRICS", help=_JSON_HELP)
def avatar(models, out, force, resume, reference, weights, components, texture_weight, json_path) -> None:
    """Blend identity MODELS into one avatar model (Nagle et al. §4, steps 5–9).

    Each model's training faces are projected into every identity, sharpened, aligned to the
    reference faceframe and morph-averaged; PCA of the blends gives DIR/model.npz.
    DIR/blend.png shows the projections and blends side by side.
    """
    from appeal.outputs import output_run
    from stimulus_engine.morphpca.io import load_model
    from stimulus_engine.morphpca.workflow import build_avatar_model

    loaded = [load_model(m) for m in models]
    wts = None
    if weights:
        try:
            wts = [float(v) for v in weights.split(",")]
        except ValueError:
            raise AppealInputError(f"--weights: expected comma-separated numbers, e.g. 0.5,0.5 (got {weights!r})") from None
    with output_run(out, force=force, resume=resume, inputs=models) as run:
        av, metrics = build_avatar_model(loaded, run.out, reference=reference, weights=wts, components=components,
                                         texture_weight=texture_weight)
        _write_metrics(run, metrics, json_path)
    click.echo(f"{run.out / 'model.npz'}: avatar of {len(loaded)} identities, {len(av.frames)} blended frames")


@morphpca.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca reconstruct models/alice/model.npz --loadings faces.csv --out faces
  appeal stimuli morphpca reconstruct avatar/model.npz --loadings proj/loadings.csv --out frames --json m.json""")
@click.argument("model_path", metavar="MODEL.npz", type=click.Path(path_type=Path))
@click.option("--loadings", required=True, type=click.Path(path_type=Path), metavar="FILE",
              help="CSV: one row per face, columns pc1..pcK (fewer = zeros; an 'image' column names the outputs).")
@out_options()
@click.option("--json", "json_path", type=click.Path(path_type=Path), default=None, metavar="METRICS", help=_JSON_HELP)
def reconstruct(model_path, loadings, out, force, resume, json_path) -> None:
    """Render faces from LOADINGS of a model (DIR/NAME.png per row)."""
    from appeal.outputs import output_run
    from stimulus_engine.morphpca.io import load_model
    from stimulus_engine.morphpca.workflow import read_loadings, reconstruct_faces

    model = load_model(model_path)
    lo, names = read_loadings(loadings, model.n_components)
    with output_run(out, force=force, resume=resume, inputs=[model_path, loadings]) as run:
        metrics = reconstruct_faces(model, lo, names, run.out)
        _write_metrics(run, metrics, json_path)
    click.echo(f"{run.out}: {metrics['faces']} face(s) in {metrics['seconds_reconstruct']:.3f} s")


@morphpca.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morphpca mimicry models/alice/model.npz models/bob/model.npz \\
      --source alice_clip/ --mimic bob_mimics_alice/ --out mimicry
  appeal stimuli morphpca mimicry A.npz B.npz --source a*.png --mimic b*.png --bins 8 --out m --json m.json
  appeal stimuli morphpca mimicry A.npz B.npz --source alice.mp4 --mimic bob.mp4 --out m    # recordings""")
@click.argument("source_model", metavar="A.npz", type=click.Path(path_type=Path))
@click.argument("mimic_model", metavar="B.npz", type=click.Path(path_type=Path))
@click.option("--source", "source_frames", multiple=True, required=True, type=click.Path(path_type=Path),
              help="Frames of A's sequence (files or folders, in name order, or a video file: .mp4, .avi, ...; "
                   "repeatable).")
@click.option("--mimic", "mimic_frames", multiple=True, required=True, type=click.Path(path_type=Path),
              help="Frames (or a video) of B mimicking it, one frame per source frame.")
@out_options()
@click.option("--no-align", is_flag=True, help="Skip the faceframe affine transform (models of equal size only).")
@click.option("--bins", type=click.IntRange(min=2), default=None,
              help="Histogram bins of the entropy / mutual-information measures (default: sqrt(frames)).")
@click.option("--json", "json_path", type=click.Path(path_type=Path), default=None, metavar="METRICS", help=_JSON_HELP)
def mimicry(source_model, mimic_model, source_frames, mimic_frames, out, force, resume, no_align, bins,
            json_path) -> None:
    """Measure how well B mimics A (Nagle et al. §5.1).

    \b
    B's frames are projected into A's expression space (the model of B encodes them, the
    faceframe affine aligns the faces, A's components take the loadings) and compared with A's
    own loadings of the source frames: per frame the Euclidean and variance-normalised distance
    and the correlation across components; per component the correlation over time, the
    Shannon entropy of each sequence and their mutual information (bits; normalised
    I / sqrt(H_A H_B): 1 = a perfect mimicry, 0 = unrelated). Writes frames.csv, components.csv,
    loadings_*.csv, loadings.png, sheet.png and mimicry.json into DIR.
    """
    from appeal.outputs import output_run
    from stimulus_engine.morphpca.io import load_model
    from stimulus_engine.morphpca.mimicry_run import measure_mimicry, mimicry_frames

    ma, mb = load_model(source_model), load_model(mimic_model)
    sf, mf = mimicry_frames(source_frames, mimic_frames, ma, mb)  # bad input: one line, before any output
    with output_run(out, force=force, resume=resume, inputs=[source_model, mimic_model, *sf.sources, *mf.sources]) as run:
        summary = measure_mimicry(ma, mb, sf, mf, run.out, align=not no_align, bins=bins)
        _write_metrics(run, summary, json_path)
    click.echo(f"{run.out}: {summary['frames']} frames; mean frame correlation {summary['mean_frame_correlation']:.2f}, "
               f"mean normalised MI {summary['mean_normalised_mi']:.2f}")
