"""Constant-temperature boxes for comparing blackbody emission with Cycles.

Run with Debian's Python and its OpenVDB 10 bindings (python3-openvdb):
    /usr/bin/python3 tests/data/cycles/make_boxes.py          # writes the files
    /usr/bin/python3 tests/data/cycles/make_boxes.py --expect # prints expectations

Writes, next to this script:
  box_thin.vdb    `density` 0.01 and `temperature` 1.0 in every voxel of the
                  index box [0,15] x [0,63] x [0,15] (16 x 64 x 16 voxels,
                  all stored as leaf voxels, background 0)
  box_fire.vdb    the same `temperature`; `density` has the same active
                  voxels, all with value 0 (active zeros)
  box_nodens.vdb  the same `temperature`; `density` has no active voxel
  box_{thin,fire}_T{0800,1500,3000,6500}.toml, box_nodens_T1500.toml
                  emission only (no lights, black world), Principled Volume
                  Density 1, Blackbody Intensity 1, Temperature T K (times the
                  temperature attribute 1.0), the camera on -Y looking
                  straight at the 1 x 1 face of the box.

The file's transform: voxel size 1/16 and a translation that centres the
box on the origin (voxel centres at (i - 7.5, j - 31.5, k - 7.5)/16), so the
box spans x, z in [-0.5, 0.5] and y in [-2, 2] between its outer voxel
centres plus half a voxel of interpolation on each side. The box is 64
voxels deep along the view axis so that its front and back faces (where
interpolation mixes the box with the zero background) weigh little against
its inside, where every lookup sees temperature 1.0.

--expect prints, for the centre rays, the radiance expected from Cycles'
formula (REFERENCE.md: intensity sigma_SB 1e-6/pi T^4 times the Rec.709 fit)
under two lookups: per-voxel (Cycles 5's stochastic one-tap lookup: the
mean emission at a point is sum w_i Le(T_i)) and interpolated temperature
(Le(sum w_i T_i)). The two differ only over the two faces.
"""
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
NX, NY, NZ = 16, 64, 16
VOXEL = 1.0 / 16.0
DENSITY = 0.01
TEMPERATURES = [800, 1500, 3000, 6500]


def write_vdbs():
    import pyopenvdb as vdb
    xf = [[VOXEL, 0, 0, 0], [0, VOXEL, 0, 0], [0, 0, VOXEL, 0],
          [-7.5 * VOXEL, -31.5 * VOXEL, -7.5 * VOXEL, 1]]

    def grid(name, value):
        g = vdb.FloatGrid(0.0)
        g.name = name
        g.transform = vdb.createLinearTransform(xf)
        g.gridClass = vdb.GridClass.FOG_VOLUME
        if value is not None:
            acc = g.getAccessor()
            for i in range(NX):
                for j in range(NY):
                    for k in range(NZ):
                        acc.setValueOn((i, j, k), value)
        return g

    for fname, dval in (('box_thin.vdb', DENSITY), ('box_fire.vdb', 0.0), ('box_nodens.vdb', None)):
        grids = [grid('density', dval), grid('temperature', 1.0)]
        vdb.write(os.path.join(HERE, fname), grids=grids)
        print(fname, [(g.name, g.activeVoxelCount(), g.evalMinMax()) for g in grids])


SCENE = """# Constant-temperature box ({what}), emission only: no lights, black world.
# Made by make_boxes.py; see README.md.
[render]
width = 32
height = 24
spp = 4096
seed = 1
max_bounces = 128

[camera]
position = [0.0, -12.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
vfov = 11.421186

[environment]
radiance = 0.0

[[volume]]
file = "{vdb}"
density_grid = "density"
temperature_grid = "temperature"
[volume.material]
density = 1.0
color = 0.5
absorption_color = 0.0
anisotropy = 0.0
blackbody_intensity = 1.0
temperature = {t:.1f}
"""


def write_scenes():
    cases = [('thin', 'density 0.01, temperature 1.0', t) for t in TEMPERATURES]
    cases += [('fire', 'density active zeros, temperature 1.0', t) for t in TEMPERATURES]
    cases += [('nodens', 'density grid empty, temperature 1.0', 1500)]
    for kind, what, t in cases:
        name = f'box_{kind}_T{t:04d}.toml'
        with open(os.path.join(HERE, name), 'w') as f:
            f.write(SCENE.format(what=what, vdb=f'box_{kind}.vdb', t=t))
        print(name)


# Cycles' svm_math_blackbody_color_rec709 (kernel/svm/math_util.h), as
# src/medium/blackbody.rs has it.
TR = [(1.6191911e3, -2.0501092e-3, 5.0299576), (2.4884547e3, -1.1133091e-3, 3.2262154),
      (3.3414319e3, -4.8655119e-4, 1.7648677), (4.0946174e3, -1.2744658e-4, 7.2573164e-1),
      (4.6702804e3, 2.912582e-5, 1.2670344e-1), (4.5950919e3, 2.8749565e-5, 1.5034502e-1),
      (3.7871745e3, 9.3590783e-6, 3.9907587e-1)]
TG = [(-4.8899975e2, 6.0433075e-4, -7.5580753e-2), (-7.5599428e2, 3.167301e-4, 4.7830614e-1),
      (-1.0236398e3, 1.2022347e-4, 9.3666232e-1), (-1.2657132e3, 4.873409e-6, 1.270545),
      (-1.4252933e3, -4.0115043e-5, 1.4397278), (-1.1755482e3, -2.1637805e-5, 1.3040802),
      (-5.0079957e2, -4.5983203e-6, 1.0909876)]
TB = [(5.9694531e-11, -4.8574289e-8, -9.7062225e-5, -4.0793615e-3),
      (2.4043037e-11, 5.5502108e-8, -1.9850371e-4, 2.8931286e-2),
      (-1.4094973e-11, 1.8987897e-7, -3.5663282e-4, 9.1076778e-2),
      (-3.6146087e-11, 2.8482201e-7, -4.9321132e-4, 1.5672344e-1),
      (-1.9707574e-11, 1.7535935e-7, -2.5054283e-4, -2.2278327e-2),
      (-1.6199796e-13, -1.6421601e-8, 3.8621627e-4, -7.3807742e-1),
      (6.7265028e-13, -2.7307881e-8, 4.2409826e-4, -7.5233569e-1)]
STARTS = [965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0]


def blackbody_rgb(t):
    if t >= 12000.0:
        return (0.8262954810464208, 0.9945080501520986, 1.566307710274283)
    if t < 800.0:
        return (5.413294490189271, -0.20319390035873933, -0.0822535242887164)
    i = sum(1 for s in STARTS if t >= s)
    r, g, b = TR[i], TG[i], TB[i]
    return (r[0] / t + r[1] * t + r[2], g[0] / t + g[1] * t + g[2],
            ((b[0] * t + b[1]) * t + b[2]) * t + b[3])


def le(t):
    """Principled Volume blackbody emission (Blackbody Intensity 1, tint 1)."""
    t = max(t, 0.0)
    k = 5.670373e-8 * 1e-6 / math.pi * t ** 4
    return [k * c for c in blackbody_rgb(t)]


def expect():
    # Along the centre ray: voxel coordinate u (voxel centres 0..63); the
    # box's trilinear weight is 1 between the outer centres and falls to 0
    # over one voxel beyond them. Midpoint rule, 1000 steps per voxel.
    steps = 1000
    print('centre-ray radiance, emission only; thin: density 0.01 (sigma_t 0.01 per unit), '
          'attenuation included, in-scattering not')
    print('case T  | per-voxel lookup (Cycles 5) R G B | interpolated T R G B | ratio interp/per-voxel R G B')
    for kind, sig in (('thin', DENSITY), ('fire', 0.0)):
        for T in TEMPERATURES:
            a = [0.0] * 3
            b = [0.0] * 3
            tau = 0.0
            u = -1.0
            du = 1.0 / steps
            le_t = le(T)
            while u < 64.0:
                um = u + du / 2
                w = 1.0 if 0 <= um <= 63 else max(0.0, 1 - (-um if um < 0 else um - 63))
                att = math.exp(-tau)
                li = le(w * T)
                for c in range(3):
                    a[c] += w * le_t[c] * att * du * VOXEL
                    b[c] += li[c] * att * du * VOXEL
                tau += sig * w * du * VOXEL
                u += du
            print(f'{kind} {T:5d} | ' + ' '.join(f'{x:.6g}' for x in a) + ' | '
                  + ' '.join(f'{x:.6g}' for x in b) + ' | '
                  + ' '.join(f'{y / x:.5f}' for x, y in zip(a, b)))


if __name__ == '__main__':
    if '--expect' in sys.argv:
        expect()
    else:
        write_vdbs()
        write_scenes()
