"""Means of float EXR images, per channel, read with Blender's image loader.

Usage:
    VENV/bin/python tools/blender/exr_stats.py A.exr [B.exr ...] \
        [--ratio-to REF.exr] [--box X0 Y0 X1 Y1] [--diff OTHER.exr]

For each image prints the image mean (over pixels and R, G, B, as
`vdbphoton compare` computes it) and the R, G, B means. --ratio-to also
prints each image's per-channel mean ratios to REF. --box restricts the
means to pixels X0 <= x < X1, Y0 <= y < Y1 (x right, y DOWN from the top
row, as vdbphoton's images are stored). --diff OTHER: for a pair of
independent renders A, OTHER of the same scene, the per-pixel standard
deviation of one render estimated as |A - OTHER| / sqrt 2 (RMS over pixels
and channels) and the standard error of the image mean estimated from it.
"""
import argparse
import sys

import bpy
import numpy as np


def load(path):
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = 'Non-Color'
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    # Blender stores rows bottom first; flip to top first.
    return px.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)


def means(a, box):
    if box:
        x0, y0, x1, y1 = box
        a = a[y0:y1, x0:x1]
    return a.mean(), a.reshape(-1, 3).mean(axis=0)


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument('images', nargs='+')
    ap.add_argument('--ratio-to')
    ap.add_argument('--box', type=int, nargs=4)
    ap.add_argument('--diff')
    a = ap.parse_args(argv)
    ref = means(load(a.ratio_to), a.box) if a.ratio_to else None
    for p in a.images:
        img = load(p)
        m, c = means(img, a.box)
        s = f'{p}: {img.shape[1]}x{img.shape[0]} mean {m:.6g}  R {c[0]:.6g}  G {c[1]:.6g}  B {c[2]:.6g}'
        if ref is not None:
            r = c / ref[1]
            s += f'  | ratio mean {m / ref[0]:.5f}  R {r[0]:.5f}  G {r[1]:.5f}  B {r[2]:.5f}'
        print(s)
    if a.diff:
        x = load(a.images[0])
        y = load(a.diff)
        if a.box:
            x0, y0, x1, y1 = a.box
            x, y = x[y0:y1, x0:x1], y[y0:y1, x0:x1]
        d = x - y
        sigma = np.sqrt((d ** 2).mean() / 2)
        # Standard error of one render's image mean: the difference's mean
        # has variance 2 var(mean).
        n = d.size
        print(f'pair {a.images[0]} - {a.diff}: per-pixel sigma (RMS) {sigma:.6g}; '
              f'mean difference {d.mean():.6g}; std error of one image mean '
              f'{d.std() / np.sqrt(2 * n):.3g} (per channel '
              + ' '.join(f'{d[..., k].std() / np.sqrt(2 * d[..., k].size):.3g}' for k in range(3))
              + f'); relative mean difference {d.mean() / ((x.mean() + y.mean()) / 2):.5f}')


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
