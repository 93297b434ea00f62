"""Intensity-weighted centroids of the blobs in an EXR image.

Usage:
    python3 tests/data/camera/centroids.py IMAGE.exr [--threshold 1e-3] [--json]

Needs numpy only (Debian's /usr/bin/python3 or the bpy venv); the EXR reader
below handles what Blender and vdbphoton write: scanline images, HALF or FLOAT
channels, compression NONE, ZIPS or ZIP.

Method (the one to port):
  1. L = (R + G + B) / 3 per pixel; pixel (i, j) has its centre at
     (i + 0.5, j + 0.5), x right, y DOWN from the top-left corner of the image
     (vdbphoton's film coordinates).
  2. A pixel belongs to a blob when L > threshold * max(L) (default 1e-3).
  3. Blobs are the 8-connected components of those pixels, found by a flood
     fill; a component with a pixel in the first or last row or column is
     marked `edge` (cut by the border: its centroid is not usable).
  4. Each component's centroid is sum(L * (i + 0.5)) / sum(L),
     sum(L * (j + 0.5)) / sum(L) over its pixels; also printed: its flux
     sum(L), pixel count and peak L.
Components are listed sorted by y, then x, of their centroid.
"""
import argparse
import json
import struct
import sys
import zlib
from collections import deque

import numpy as np


def read_exr(path):
    """RGB(A) channels of a scanline EXR as float64 arrays, rows top first."""
    with open(path, 'rb') as f:
        data = f.read()
    if data[:4] != b'\x76\x2f\x31\x01':
        raise ValueError(f'{path}: not an OpenEXR file')
    flags = struct.unpack_from('<I', data, 4)[0]
    if flags & 0x200 or flags & 0x1000:
        raise ValueError(f'{path}: tiled or multi-part EXR not supported')
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b'\0', pos)
        name = data[pos:end].decode()
        pos = end + 1
        end = data.index(b'\0', pos)
        typ = data[pos:end].decode()
        pos = end + 1
        size = struct.unpack_from('<i', data, pos)[0]
        pos += 4
        attrs[name] = (typ, data[pos:pos + size])
        pos += size
    pos += 1
    chans, raw = [], attrs['channels'][1]
    p = 0
    while raw[p] != 0:
        end = raw.index(b'\0', p)
        name = raw[p:end].decode()
        ptype, _, xs, ys = struct.unpack_from('<iB3xii', raw, end + 1)
        if xs != 1 or ys != 1:
            raise ValueError(f'{path}: subsampled channel {name}')
        chans.append((name, ptype))
        p = end + 1 + 16
    x0, y0, x1, y1 = struct.unpack('<iiii', attrs['dataWindow'][1])
    comp = attrs['compression'][1][0]
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lines_per_block = {0: 1, 2: 1, 3: 16}.get(comp)
    if lines_per_block is None:
        raise ValueError(f'{path}: compression {comp} not supported (NONE, ZIPS, ZIP only)')
    nblocks = (h + lines_per_block - 1) // lines_per_block
    offsets = struct.unpack_from(f'<{nblocks}Q', data, pos)
    sizes = {0: 4, 1: 2, 2: 4}                      # UINT, HALF, FLOAT
    dtypes = {0: '<u4', 1: '<f2', 2: '<f4'}
    out = {name: np.zeros((h, w)) for name, _ in chans}
    for off in offsets:
        y, n = struct.unpack_from('<ii', data, off)
        block = data[off + 8:off + 8 + n]
        nl = min(lines_per_block, y1 - y + 1)
        expect = nl * w * sum(sizes[t] for _, t in chans)
        if comp != 0 and n < expect:
            b = np.frombuffer(zlib.decompress(block), dtype=np.uint8).astype(np.int32)
            # Undo the predictor, then the interleaving of the two halves.
            b = (np.cumsum(np.concatenate(([b[0]], b[1:] - 128))) & 0xFF).astype(np.uint8)
            half = (len(b) + 1) // 2
            t = np.empty(len(b), dtype=np.uint8)
            t[0::2] = b[:half]
            t[1::2] = b[half:]
            block = t.tobytes()
        q = 0
        for line in range(nl):
            for name, t in chans:
                nb = w * sizes[t]
                out[name][y - y0 + line] = np.frombuffer(block[q:q + nb], dtype=dtypes[t])
                q += nb
    return out


def blobs(img, threshold=1e-3):
    L = (img['R'] + img['G'] + img['B']) / 3.0
    h, w = L.shape
    mask = L > threshold * L.max()
    seen = np.zeros_like(mask)
    found = []
    for j0, i0 in zip(*np.nonzero(mask)):
        if seen[j0, i0]:
            continue
        seen[j0, i0] = True
        queue, pix = deque([(j0, i0)]), []
        while queue:
            j, i = queue.popleft()
            pix.append((j, i))
            for dj in (-1, 0, 1):
                for di in (-1, 0, 1):
                    jj, ii = j + dj, i + di
                    if 0 <= jj < h and 0 <= ii < w and mask[jj, ii] and not seen[jj, ii]:
                        seen[jj, ii] = True
                        queue.append((jj, ii))
        js = np.array([p[0] for p in pix])
        is_ = np.array([p[1] for p in pix])
        v = L[js, is_]
        s = v.sum()
        found.append(dict(x=float((v * (is_ + 0.5)).sum() / s), y=float((v * (js + 0.5)).sum() / s),
                          flux=float(s), pixels=len(pix), peak=float(v.max()),
                          edge=bool(js.min() == 0 or is_.min() == 0 or js.max() == h - 1
                                    or is_.max() == w - 1)))
    found.sort(key=lambda b: (b['y'], b['x']))
    return found, (w, h)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('image')
    ap.add_argument('--threshold', type=float, default=1e-3,
                    help='fraction of the image maximum (default 1e-3)')
    ap.add_argument('--json', action='store_true')
    a = ap.parse_args(argv)
    found, (w, h) = blobs(read_exr(a.image), a.threshold)
    if a.json:
        print(json.dumps(dict(image=a.image, width=w, height=h, blobs=found), indent=1))
        return 0
    print(f'{a.image}: {w}x{h}, {len(found)} blobs')
    print('     x          y        flux     pixels  peak      edge')
    for b in found:
        print(f"{b['x']:10.4f} {b['y']:10.4f} {b['flux']:11.5g} {b['pixels']:5d} {b['peak']:10.4g}"
              f"  {'edge' if b['edge'] else ''}")
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
