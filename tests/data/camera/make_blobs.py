"""Emissive blobs and camera scenes for checking vdbphoton's camera against
Blender's (pixel placement, sensor fit, shift, orientation keys).

Run with Debian's Python and its OpenVDB 10 bindings (python3-openvdb):
    /usr/bin/python3 tests/data/camera/make_blobs.py

Writes, next to this script:
  blobs.vdb     one float grid `density`, voxel size 0.02, index (i, j, k)
                at world (i, j, k) * 0.02 - 1.28 (all indices in 0..127, one
                internal node of each level, a small file), holding small smooth
                balls: density (1 - (r/R)^2)^2 for r < R = 0.06 (3 voxels)
                around centres that sit on voxel centres, 0 (inactive)
                elsewhere. Each ball's trilinearly interpolated density is
                mirror-symmetric about its centre in x, y and z, so the
                centroid of its emission is exactly the centre.
  blobs.json    the ball centres (world units), in the order of their ids
  *.toml        one scene per camera (CAMERAS below): emission only (raw
                `emission` = 50 per unit density, no scattering, no
                absorption), no lights, black world.

The centres are drawn at random (fixed seed) inside x, y in [-1, 1], z in
[-0.7, 0.7]; a candidate is kept only if, in every camera, its projection is
at least GAP pixels from every ball kept before (between the edges of their
projected spheres) and its edge at least MARGIN pixels
from the image border (inside or outside it), so that every ball a camera
sees is a separate blob away from the border. The projection used for that
choice is the formula of README.md; the check of that formula against
Blender is project_blender.py, independent of this script.
"""
import json
import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))
VOXEL = 0.02
ORIGIN = -1.28                  # world position of index (0, 0, 0), on each axis
R_VOX = 3.0                     # ball radius in voxels
RADIUS = R_VOX * VOXEL          # 0.06 world units
EMISSION = 50.0
BOX = ((-1.0, 1.0), (-1.0, 1.0), (-0.7, 0.7))
N_BALLS = 40
GAP = 3.0                       # pixels between the projected balls' edges, in every camera
MARGIN = 2.0                    # pixels between a projected ball's edge and the image border
SEED = 7


def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return [[1, 0, 0], [0, c, -s], [0, s, c]]


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return [[c, 0, s], [0, 1, 0], [-s, 0, c]]


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return [[c, -s, 0], [s, c, 0], [0, 0, 1]]


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def euler_xyz(deg):
    """Blender's XYZ Euler: R = Rz * Ry * Rx."""
    rx, ry, rz = (math.radians(d) for d in deg)
    return mul(rot_z(rz), mul(rot_y(ry), rot_x(rx)))


def look_at_rotation(pos, target, up=(0, 0, 1), roll_deg=0.0):
    """Camera rotation (columns: right, up, back = Blender's camera axes)
    looking from pos to target, then rolled about the view axis."""
    f = [t - p for t, p in zip(target, pos)]
    n = math.sqrt(sum(x * x for x in f))
    f = [x / n for x in f]
    r = [f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0]]
    n = math.sqrt(sum(x * x for x in r))
    r = [x / n for x in r]
    u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]]
    b = [-x for x in f]
    c, s = math.cos(math.radians(roll_deg)), math.sin(math.radians(roll_deg))
    r2 = [c * x + s * y for x, y in zip(r, u)]
    u2 = [-s * x + c * y for x, y in zip(r, u)]
    return [[r2[i], u2[i], b[i]] for i in range(3)]


# Cameras. `keys` are written to [camera] as given (plus the derived pose);
# pose: ('euler', rotation_deg, distance) puts the camera at that distance
# from the origin along its back axis (location rounded to 1e-3), written
# as location + rotation; ('matrix', position, roll_deg) looks at the origin
# and rolls, written as a 4 x 4 matrix; ('lookat', position) writes
# position/look_at/up.
CAMERAS = [
    dict(name='land_auto', size=(160, 90), pose=('euler', [63.5, 5.0, 46.5], 5.0),
         keys=dict(focal_length=50.0, sensor_fit='auto', sensor_height=30.0),
         note='landscape, sensor fit auto (= horizontal, sensor_width 36 across the width; '
              'sensor_height is ignored), location + rotation with a roll'),
    dict(name='land_vertical', size=(160, 90), pose=('matrix', [-2.9, -2.0, -1.45], 15.0),
         keys=dict(focal_length=40.0, sensor_fit='vertical', sensor_width=30.0,
                   sensor_height=20.0),
         note='landscape, sensor fit vertical (sensor_height 20 across the height), '
              'matrix from below with a 15 degree roll'),
    dict(name='land_horizontal_shift', size=(160, 90), pose=('euler', [101.0, -8.0, -130.0], 3.9),
         keys=dict(focal_length=30.0, sensor_fit='horizontal', sensor_width=32.0,
                   sensor_height=18.0, shift_x=0.12, shift_y=-0.08),
         note='landscape, sensor fit horizontal, shift (units: the width)'),
    dict(name='land_vertical_shift', size=(160, 90), pose=('matrix', [1.95, 3.45, 0.75], -7.0),
         keys=dict(focal_length=45.0, sensor_fit='vertical', shift_x=-0.1, shift_y=0.15),
         note='landscape, sensor fit vertical (sensor_height 24 by default), shift '
              '(units: the height, the fitted dimension, not the larger one)'),
    dict(name='port_auto', size=(90, 160), pose=('euler', [58.0, -3.0, -35.0], 4.4),
         keys=dict(focal_length=50.0, sensor_fit='auto', sensor_width=36.0, sensor_height=50.0),
         note='portrait, sensor fit auto (= vertical fit but with sensor_width 36 across the '
              'height; sensor_height 50 is ignored), location + rotation'),
    dict(name='port_horizontal', size=(90, 160), pose=('matrix', [0.25, -2.6, 1.9], 0.0),
         keys=dict(focal_length=24.0, sensor_fit='horizontal', sensor_width=24.0),
         note='portrait, sensor fit horizontal (sensor_width 24 across the width), matrix'),
    dict(name='port_vertical', size=(90, 160), pose=('matrix', [5.7, 1.4, -1.0], 25.0),
         keys=dict(focal_length=60.0, sensor_fit='vertical', sensor_width=20.0,
                   sensor_height=30.0),
         note='portrait, sensor fit vertical (sensor_height 30 across the height; '
              'sensor_width is ignored), matrix with a 25 degree roll'),
    dict(name='port_auto_shift', size=(90, 160), pose=('euler', [75.0, 10.0, 160.0], 4.4),
         keys=dict(focal_length=35.0, sensor_width=30.0, shift_x=0.07, shift_y=-0.1),
         note='portrait, sensor fit auto by default (sensor_width 30 across the height), shift '
              '(units: the height, the larger dimension), location + rotation'),
    dict(name='land_vfov_shift', size=(160, 90), pose=('lookat', [-1.15, -4.65, 1.05]),
         keys=dict(vfov=26.0, shift_x=0.05, shift_y=0.1),
         note='landscape, the vfov key (sensor fit vertical) with shift (units: the height), '
              'position/look_at/up'),
]


def camera_model(cam):
    """(rotation 3x3 with columns right, up, back; position; f_px; shift in px)."""
    w, h = cam['size']
    k = cam['keys']
    kind = cam['pose'][0]
    if kind == 'euler':
        rot = euler_xyz(cam['pose'][1])
        back = [rot[i][2] for i in range(3)]
        pos = [round(cam['pose'][2] * b, 3) for b in back]
    elif kind == 'matrix':
        pos = cam['pose'][1]
        rot = look_at_rotation(pos, (0, 0, 0), roll_deg=cam['pose'][2])
    else:
        pos = cam['pose'][1]
        rot = look_at_rotation(pos, (0, 0, 0))
    if 'vfov' in k:
        horizontal = False
        fpx = 0.5 * h / math.tan(math.radians(k['vfov']) / 2)
        dim = h
    else:
        fit = k.get('sensor_fit', 'auto')
        horizontal = (w >= h) if fit == 'auto' else fit == 'horizontal'
        sensor = k.get('sensor_height', 24.0) if fit == 'vertical' else k.get('sensor_width', 36.0)
        dim = w if horizontal else h
        fpx = k['focal_length'] / sensor * dim
    shift = (k.get('shift_x', 0.0) * dim, k.get('shift_y', 0.0) * dim)
    return rot, pos, fpx, shift


def project(cam, model, p):
    """Pixel position (x right, y down, (0, 0) the top-left image corner) of
    world point p, and its depth in front of the camera."""
    rot, pos, fpx, (sx, sy) = model
    w, h = cam['size']
    d = [a - b for a, b in zip(p, pos)]
    x = sum(rot[i][0] * d[i] for i in range(3))
    y = sum(rot[i][1] * d[i] for i in range(3))
    z = -sum(rot[i][2] * d[i] for i in range(3))
    return (w / 2 + fpx * x / z - sx, h / 2 - fpx * y / z + sy, z)


def toml_value(v):
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, list):
        return '[' + ', '.join(toml_value(x) for x in v) + ']'
    return str(v)


def write_scene(cam, model):
    rot, pos, _, _ = model
    w, h = cam['size']
    lines = [f"# Camera test: {cam['note']}.",
             '# Emission only (raw emission per unit density, no scattering or absorption),',
             '# no lights, black world. Made by make_blobs.py; see README.md.',
             '[render]', f'width = {w}', f'height = {h}', 'spp = 2048', 'seed = 1',
             'max_bounces = 0', '', '[camera]']
    kind = cam['pose'][0]
    if kind == 'euler':
        lines.append(f'location = {toml_value([float(x) for x in pos])}')
        lines.append(f"rotation = {toml_value([float(x) for x in cam['pose'][1]])}")
    elif kind == 'matrix':
        lines.append('matrix = [')
        for i in range(3):
            row = [float(f'{rot[i][j]:.9f}') for j in range(3)] + [float(pos[i])]
            lines.append(f'  {toml_value(row)},')
        lines.append('  [0.0, 0.0, 0.0, 1.0],')
        lines.append(']')
    else:
        lines.append(f'position = {toml_value([float(x) for x in pos])}')
        lines.append('look_at = [0.0, 0.0, 0.0]')
        lines.append('up = [0.0, 0.0, 1.0]')
    for k, v in cam['keys'].items():
        lines.append(f'{k} = {toml_value(v)}')
    lines += ['', '[environment]', 'radiance = 0.0', '', '[[volume]]', 'file = "blobs.vdb"',
              '[volume.material]', f'emission = {EMISSION}', '']
    with open(os.path.join(HERE, cam['name'] + '.toml'), 'w') as f:
        f.write('\n'.join(lines))


def choose_centres():
    rng = random.Random(SEED)
    models = [camera_model(c) for c in CAMERAS]
    cands = []
    for a, b in BOX:
        lo, hi = math.ceil((a - ORIGIN) / VOXEL), math.floor((b - ORIGIN) / VOXEL)
        cands.append(list(range(lo, hi + 1)))
    kept, proj = [], []
    for _ in range(300000):
        if len(kept) == N_BALLS:
            break
        idx = [rng.choice(c) for c in cands]
        if idx in kept:
            continue
        p = [ORIGIN + i * VOXEL for i in idx]
        pp = [project(c, m, p) for c, m in zip(CAMERAS, models)]
        ok = True
        for (x, y, z), c, m in zip(pp, CAMERAS, models):
            w, h = c['size']
            if z <= 0:
                ok = False
                break
            e = MARGIN + RADIUS * m[2] / z
            inside = e <= x <= w - e and e <= y <= h - e
            outside = x < -e or x > w + e or y < -e or y > h + e
            if not (inside or outside):
                ok = False
                break
        if ok:
            for q in proj:
                if any(math.hypot(a[0] - b[0], a[1] - b[1])
                       < GAP + RADIUS * m[2] * (1 / a[2] + 1 / b[2])
                       for a, b, m in zip(pp, q, models)):
                    ok = False
                    break
        if ok:
            kept.append(idx)
            proj.append(pp)
    return kept, models, proj


def write_vdb(centres):
    import pyopenvdb as vdb
    g = vdb.FloatGrid(0.0)
    g.name = 'density'
    g.transform = vdb.createLinearTransform([[VOXEL, 0, 0, 0], [0, VOXEL, 0, 0],
                                             [0, 0, VOXEL, 0], [ORIGIN, ORIGIN, ORIGIN, 1]])
    g.gridClass = vdb.GridClass.FOG_VOLUME
    acc = g.getAccessor()
    r = math.ceil(R_VOX)
    for c in centres:
        for i in range(-r, r + 1):
            for j in range(-r, r + 1):
                for k in range(-r, r + 1):
                    s2 = (i * i + j * j + k * k) / (R_VOX * R_VOX)
                    if s2 < 1.0:
                        acc.setValueOn((c[0] + i, c[1] + j, c[2] + k), (1.0 - s2) ** 2)
    vdb.write(os.path.join(HERE, 'blobs.vdb'), grids=[g])


def main():
    centres, models, proj = choose_centres()
    print(f'{len(centres)} balls')
    for c, m in zip(CAMERAS, models):
        write_scene(c, m)
        vis = sum(1 for pp in proj
                  if 0 <= pp[CAMERAS.index(c)][0] <= c['size'][0]
                  and 0 <= pp[CAMERAS.index(c)][1] <= c['size'][1])
        print(f"{c['name']}: f = {m[2]:.2f} px, {vis} balls in the frame")
    write_vdb(centres)
    with open(os.path.join(HERE, 'blobs.json'), 'w') as f:
        json.dump({'voxel_size': VOXEL, 'radius': RADIUS,
                   'profile': '(1 - (r/R)^2)^2', 'emission': EMISSION,
                   'origin': ORIGIN,
                   'centres': [[round(ORIGIN + i * VOXEL, 6) for i in c] for c in centres]}, f, indent=1)
        f.write('\n')


if __name__ == '__main__':
    main()
