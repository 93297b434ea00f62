"""A glowing box moving diagonally across the view, for motion blur against Cycles.

Run with Debian's Python and its OpenVDB 10 bindings (python3-openvdb):
    /usr/bin/python3 tests/data/cycles/make_moving_box.py

Writes, next to this script:
  moving_box.vdb   `density` 1 in the voxels of the index box [0,11]^3
                   (voxel 1/40: a cube 0.3 wide, centred on the origin), and
                   `velocity` (vec3s) = (VX, 0, VZ) units per second in every
                   voxel of [-32,39]^3 (the cube and 0.7 units around it, as tiles, so
                   that every displaced lookup finds the velocity: Cycles and
                   vdbphoton both leave a lookup where it is outside the
                   velocity grid's voxels)
  moving_box_center.toml   emission only (raw emission 6, no extinction),
                   motion blur with Blender's defaults (shutter 0.5 frames,
                   centred, 24 fps), the camera on -Y looking at the cube,
                   which then moves along the image's diagonal
  moving_box_start_frame.toml  the same with shutter_position "start",
                   shutter 1.0 and the velocity given per frame (VX/24, 0,
                   VZ/24 as velocity_scale 1/24 of the file's per-second
                   vectors), where Cycles ignores the shutter and
                   render_cycles.py makes up for it

The smear over the shutter is (VX, VZ) x shutter / fps units: 0.125 units
along each axis for the centred shutter (25 px at 160 x 120 with this
camera), twice that at the start-shutter one. tests/cycles.rs measures it in
pixels from the image's second moments.
"""
import os

HERE = os.path.dirname(os.path.abspath(__file__))
VOXEL = 1.0 / 40.0
N = 12
VX, VZ = 6.0, 6.0

SCENE = """# A glowing cube moving diagonally (make_moving_box.py), emission only, motion blur.
# Cycles references: see README.md.
[render]
width = 160
height = 120
spp = 256
seed = 1
max_bounces = 8
motion_blur = true
{render}

[camera]
position = [0.0, -6.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
vfov = 8.0

[environment]
radiance = 0.0

[[volume]]
file = "moving_box.vdb"
{volume}
[volume.material]
emission = 6.0
"""


def write():
    import pyopenvdb as vdb
    c = -(N - 1) / 2 * VOXEL
    xf = [[VOXEL, 0, 0, 0], [0, VOXEL, 0, 0], [0, 0, VOXEL, 0], [c, c, c, 1]]
    d = vdb.FloatGrid(0.0)
    d.name = 'density'
    d.transform = vdb.createLinearTransform(xf)
    d.gridClass = vdb.GridClass.FOG_VOLUME
    d.fill((0, 0, 0), (N - 1, N - 1, N - 1), 1.0, True)
    v = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    v.name = 'velocity'
    v.transform = vdb.createLinearTransform(xf)
    v.fill((-32, -32, -32), (39, 39, 39), (VX, 0.0, VZ), True)
    vdb.write(os.path.join(HERE, 'moving_box.vdb'), grids=[d, v])
    with open(os.path.join(HERE, 'moving_box_center.toml'), 'w') as f:
        f.write(SCENE.format(render='', volume=''))
    with open(os.path.join(HERE, 'moving_box_start_frame.toml'), 'w') as f:
        f.write(SCENE.format(render='shutter = 1.0\nshutter_position = "start"',
                             volume='velocity_unit = "frame"\n'
                                    'velocity_scale = 0.041666666666666664'))


if __name__ == '__main__':
    write()
