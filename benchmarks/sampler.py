"""The bilinear sampler (stimulus_engine.geometry.sampling, cv2.remap) against a float64 NumPy sampler.

The NumPy sampler is the one texture transfer used before (gather the four neighbours in
float64, clamp coordinates at the border). Printed: median milliseconds of both and their
ratio, for texture-transfer lookups (512 x 512 random UVs, some beyond the borders, in the
2400 x 1600 james texture; needs ../shared/data, else a random image) and for a 240 x 200
warp; the largest difference in 8-bit levels and how many lookups round to another level;
and whether fractions are quantised (a ramp sampled at 1,001 positions between two pixels).

Run: .venv/bin/python benchmarks/sampler.py [--repeats 10]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import timeit
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from appeal.assets import shared_data_dir  # noqa: E402
from stimulus_engine.geometry.sampling import sample_points, uv_to_pixels  # noqa: E402


def numpy_bilinear(image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Float64 bilinear samples (K, c) of ``image`` at pixel positions ``xy`` (K, 2), clamped."""
    h, w = image.shape[:2]
    x, y = np.clip(xy[:, 0], 0, w - 1), np.clip(xy[:, 1], 0, h - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    xs, ys = (x0, np.minimum(x0 + 1, w - 1)), (y0, np.minimum(y0 + 1, h - 1))
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    out = 0.0
    for j, wy in ((0, 1 - fy), (1, fy)):
        for i, wx in ((0, 1 - fx), (1, fx)):
            out = out + wy * wx * image[ys[j], xs[i]].astype(np.float64).reshape(len(xy), -1)
    return out


def _ms(fn, repeats: int) -> float:
    return 1e3 * statistics.median(timeit.repeat(fn, number=1, repeat=repeats))


def _image(rng) -> tuple[str, np.ndarray]:
    d = shared_data_dir()
    path = None if d is None else d / "meshes" / "menpo3d-james" / "james.jpg"
    if path is not None and path.exists():
        from PIL import Image

        return path.name, np.asarray(Image.open(path).convert("RGB"))
    return "random 1600 x 2400", rng.integers(0, 256, size=(1600, 2400, 3), dtype=np.uint8)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    name, img = _image(rng)
    xy = uv_to_pixels(rng.uniform(-0.01, 1.01, size=(512 * 512, 2)), img.shape[1], img.shape[0])
    ref, got = numpy_bilinear(img, xy), sample_points(img, xy)
    d = np.abs(got - ref)
    rounded = int((np.rint(got) != np.rint(ref)).any(axis=1).sum())
    print(f"{name}: {len(xy)} lookups; cv2 {_ms(lambda: sample_points(img, xy), args.repeats):.1f} ms, "
          f"numpy {_ms(lambda: numpy_bilinear(img, xy), args.repeats):.1f} ms; max |diff| {d.max():.3f} levels, "
          f"{rounded} lookups round to another level")
    field = rng.random((240, 200, 3)).astype(np.float32)
    yy, xx = np.mgrid[0:240, 0:200]
    wxy = np.column_stack([xx.ravel(), yy.ravel()]) + rng.normal(0, 3, size=(240 * 200, 2))
    t_cv, t_np = _ms(lambda: sample_points(field, wxy), args.repeats), _ms(lambda: numpy_bilinear(field, wxy), args.repeats)
    print(f"240 x 200 warp: cv2 {t_cv:.2f} ms, numpy {t_np:.2f} ms, ratio {t_np / t_cv:.0f}")
    ramp = np.tile(np.arange(8, dtype=np.float32), (3, 1))
    x = np.linspace(2, 3, 1001)
    vals = sample_points(ramp, np.column_stack([x, np.ones_like(x)]))[:, 0]
    print(f"ramp: {len(np.unique(vals))} distinct values at 1001 positions, max error {np.abs(vals - x).max():.2e}")


if __name__ == "__main__":
    main()
