"""Checks the camera scenes against Blender's own camera math.

Usage (from the repository root, with the bpy 5.0.1 venv):
    /work/venv-bpy/bin/python tests/data/camera/project_blender.py [NAME ...] [--exr-dir DIR]

For each scene NAME.toml (default: every camera of make_blobs.py), builds
the Blender scene exactly as tools/blender/render_cycles.py does (its own
functions), then projects every ball centre of blobs.json with Blender's
`bpy_extras.object_utils.world_to_camera_view` (normalised frame
coordinates, y up) and converts it to pixels: x = u * W, y = (1 - v) * H
(x right, y down, (0, 0) the top-left corner, as vdbphoton's film and
centroids.py count). It prints, per camera:
  - the largest difference between Blender's projection and the closed-form
    formula of README.md (make_blobs.project), which vdbphoton implements;
  - for NAME_cycles.exr in DIR (default: this folder), each blob's measured
    centroid (centroids.py) minus Blender's projected centre, matched to the
    nearest projected centre within 1.5 px, and the mean, RMS and largest
    difference. Centres closer than 1 px + their projected radius to the
    border are not matched.
--json OUT writes the matched table (per camera: ball id, Blender's projected
centre x, y, Cycles' centroid x, y, flux and pixel count) for tests;
cycles_centroids.json here is that table.
"""
import argparse
import json
import math
import os
import sys
import types

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, '..', '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'tools', 'blender'))
sys.path.insert(0, HERE)

import render_cycles  # noqa: E402  (imports bpy)
import make_blobs  # noqa: E402
import centroids  # noqa: E402
from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from mathutils import Vector  # noqa: E402


def blender_projection(name, centres):
    path = os.path.join(HERE, name + '.toml')
    desc = render_cycles.load_scene(path)
    args = types.SimpleNamespace(width=None, height=None, spp=None, seed=None, threads=2,
                                 half=False)
    scene, info, _ = render_cycles.build_scene(desc, args, HERE, None, [])
    w, h = info['width'], info['height']
    cam = scene.camera
    out = []
    for c in centres:
        u, v, z = world_to_camera_view(scene, cam, Vector(c))
        out.append((u * w, (1.0 - v) * h, z))
    return out, (w, h)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('names', nargs='*')
    ap.add_argument('--exr-dir', default=HERE)
    ap.add_argument('--json')
    a = ap.parse_args(argv)
    names = a.names or [c['name'] for c in make_blobs.CAMERAS]
    with open(os.path.join(HERE, 'blobs.json')) as f:
        blob_info = json.load(f)
    centres, radius = blob_info['centres'], blob_info['radius']
    table = {}
    for name in names:
        cam = next(c for c in make_blobs.CAMERAS if c['name'] == name)
        model = make_blobs.camera_model(cam)
        proj, (w, h) = blender_projection(name, centres)
        formula = [make_blobs.project(cam, model, c) for c in centres]
        dform = max(math.hypot(p[0] - q[0], p[1] - q[1]) for p, q in zip(proj, formula))
        print(f'{name}: {w}x{h}, formula vs Blender projection: max {dform:.2e} px')
        exr = os.path.join(a.exr_dir, name + '_cycles.exr')
        if not os.path.exists(exr):
            print(f'  (no {exr})')
            continue
        found, _ = centroids.blobs(centroids.read_exr(exr))
        rows, used = [], set()
        fpx = model[2]
        for k, (x, y, z) in enumerate(proj):
            r = radius * fpx / z
            e = 1.0 + r
            if not (e <= x <= w - e and e <= y <= h - e):
                continue
            best = min(range(len(found)),
                       key=lambda i: math.hypot(found[i]['x'] - x, found[i]['y'] - y))
            b = found[best]
            d = math.hypot(b['x'] - x, b['y'] - y)
            if d > 1.5 or b['edge']:
                print(f'  ball {k}: projected ({x:.3f}, {y:.3f}) has no blob within 1.5 px')
                continue
            used.add(best)
            rows.append(dict(ball=k, x=x, y=y, cx=b['x'], cy=b['y'], dx=b['x'] - x,
                             dy=b['y'] - y, r_px=r, flux=b['flux'], pixels=b['pixels']))
        extra = [i for i, b in enumerate(found) if i not in used and not b['edge']]
        dx = [r_['dx'] for r_ in rows]
        dy = [r_['dy'] for r_ in rows]
        dd = [math.hypot(p, q) for p, q in zip(dx, dy)]
        n = len(rows)
        print(f'  {n} blobs matched ({len(extra)} unmatched inside, '
              f"{sum(1 for b in found if b['edge'])} at the border): Cycles centroid - projected "
              f'centre: mean dx {sum(dx) / n:+.4f} dy {sum(dy) / n:+.4f}, RMS '
              f'{math.sqrt(sum(d * d for d in dd) / n):.4f}, max {max(dd):.4f} px')
        for r_ in rows:
            print(f"    ball {r_['ball']:2d}: projected ({r_['x']:9.4f}, {r_['y']:9.4f})  Cycles "
                  f"({r_['cx']:9.4f}, {r_['cy']:9.4f})  diff ({r_['dx']:+.4f}, {r_['dy']:+.4f})  "
                  f"radius {r_['r_px']:.2f} px")
        table[name] = dict(width=w, height=h, blobs=[
            dict(ball=r_['ball'], projected=[round(r_['x'], 4), round(r_['y'], 4)],
                 cycles=[round(r_['cx'], 4), round(r_['cy'], 4)], flux=round(r_['flux'], 4),
                 pixels=r_['pixels']) for r_ in rows])
    if a.json:
        with open(a.json, 'w') as f:
            cams = []
            for name, t in table.items():
                blobs = ',\n'.join('    ' + json.dumps(b) for b in t['blobs'])
                cams.append(f'  {json.dumps(name)}: {{"width": {t["width"]}, '
                            f'"height": {t["height"]}, "blobs": [\n{blobs}\n  ]}}')
            f.write('{\n' + ',\n'.join(cams) + '\n}\n')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
