"""Build (and optionally bake) the "From Blender" shot of tools/blender/README.md:
a Mantaflow smoke + fire domain placed as blender_smoke/make_smoke_info.json
describes it, with Blender's Quick Smoke fire material, lit by a sun and a dim
sky, 320 x 240.

Usage:
    blender -b -P tools/blender/test_export/build_fire_shot.py -- OUT.blend \
        --cache CACHEDIR [--bake]                                # Blender 3.4.1 (Debian)
    VENV/bin/python tools/blender/test_export/build_fire_shot.py OUT.blend \
        --cache CACHEDIR                                         # bpy 5.0.1, existing cache

The scene:
  domain     a 2 x 2 x 2 cube at (0, 0, 1) scaled (1.25, 1.25, 2.25) (world box
             [-1.25, 1.25]^2 x [-1.25, 3.25]), gas, Resolution Divisions 64
             (36 x 36 x 64 cells), cache type All, OpenVDB float32 Blosc,
             frames 1-40, no adaptive domain, Flame Ignition 1.5, Maximum Temperature 3.0: the
             settings of make_smoke_info.json.
  material   Quick Smoke with fire (Blender's object_quick_effects.py): a
             Principled Volume with Density 5 and Blackbody Intensity 1, the
             rest default (Color 0.5, Temperature 1000 K x attribute
             'temperature', which Blender makes from the flame grid).
  flow       a sphere of radius 0.22 at (0, 0, -0.12), Fire + Smoke, inflow
             from the mesh (fuel 1, temperature 1: defaults). Blender gives the
             domain fire (loads its flame grid) only with such a flow, so it
             stays in the scene; its ray visibility is all off, so Cycles
             renders nothing of it (the exporter skips it).
  lights     a sun of Strength 2 (colour 1, 0.95, 0.9) shining from direction
             (0.6, -0.4, 0.7), angle 0.5 degrees; a world colour
             (0.03, 0.035, 0.045).
  camera     at (0, -6, 1.05) looking along +Y, 50 mm lens on a 36 mm sensor.
  render     320 x 240, Cycles 256 samples, seed 0, Max Bounces 16, Volume
             Bounces 15 (vdbphoton max_bounces 16), frames 1-40, output
             //render/fire_####, Standard view transform.

CACHEDIR is set as the domain's Cache Directory last (changing a domain
setting afterwards makes Blender delete the cache). --bake (Blender 3.4.1;
the pip bpy module cannot bake) bakes frames 1-40 into it before saving.
With an existing cache (e.g. /work/shared/data/blender_smoke's frames copied
to CACHEDIR/data/fluid_data_0025.vdb), build without --bake.
"""
import math
import os
import sys
import time

import bpy
from mathutils import Vector

# The scene helpers of the exporter's test scenes, beside this file.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from build_scene import (cube_mesh, fire_flow, link, new_scene,  # noqa: E402
                         quick_smoke_fire, world_colour)


def args():
    a = sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:]
    out = a[0]
    cache = a[a.index('--cache') + 1]
    return os.path.abspath(out), os.path.abspath(cache), '--bake' in a


def main():
    out, cache, bake = args()
    sc = new_scene()

    r = sc.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = 320, 240, 100
    r.filepath = '//render/fire_####'
    sc.frame_start, sc.frame_end, sc.frame_current = 1, 40, 25
    cy = sc.cycles
    cy.samples = 256
    cy.seed = 0
    cy.max_bounces = 16
    cy.volume_bounces = 15
    sc.view_settings.view_transform = 'Standard'

    cam = bpy.data.cameras.new('Camera')
    cam.lens = 50.0
    cam.sensor_width = 36.0
    cam.sensor_fit = 'AUTO'
    co = link(sc, 'Camera', cam)
    co.location = (0.0, -6.0, 1.05)
    co.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    sc.camera = co

    sun = bpy.data.lights.new('Sun', 'SUN')
    sun.energy = 2.0
    sun.color = (1.0, 0.95, 0.9)
    sun.angle = math.radians(0.5)
    so = link(sc, 'Sun', sun)
    so.rotation_mode = 'QUATERNION'
    # The sun shines along its local -Z: +Z points towards it.
    so.rotation_quaternion = Vector((0.6, -0.4, 0.7)).normalized().to_track_quat('Z', 'Y')

    world_colour(sc, (0.03, 0.035, 0.045))

    # Fire + Smoke flow: fuel 1 and temperature 1 from the mesh (Blender's
    # defaults, set so that the shot does not depend on them).
    fo = fire_flow(sc, 'Emitter', (0.0, 0.0, -0.12), radius=0.22, segments=(24, 12))
    fs = fo.modifiers['Fluid'].flow_settings
    fs.flow_source = 'MESH'
    fs.fuel_amount = 1.0
    fs.temperature = 1.0
    fo.display_type = 'WIRE'

    # Domain.
    do = link(sc, 'Smoke Domain', cube_mesh('Smoke Domain'))
    do.location = (0.0, 0.0, 1.0)
    do.scale = (1.25, 1.25, 2.25)
    do.display_type = 'WIRE'
    m = do.modifiers.new('Fluid', 'FLUID')
    m.fluid_type = 'DOMAIN'
    ds = m.domain_settings
    ds.domain_type = 'GAS'
    ds.resolution_max = 64
    ds.use_adaptive_domain = False
    ds.cache_type = 'ALL'
    ds.cache_data_format = 'OPENVDB'
    ds.openvdb_data_depth = '32'
    try:
        ds.openvdb_cache_compress_type = 'BLOSC'
    except TypeError:
        pass  # Blender 5 offers ZIP and none only (it reads Blosc caches)
    ds.cache_frame_start = 1
    ds.cache_frame_end = 40
    ds.flame_ignition = 1.5
    ds.flame_max_temp = 3.0
    ds.alpha = 1.0
    ds.beta = 1.0
    ds.vorticity = 0.0
    ds.time_scale = 1.0

    do.data.materials.append(quick_smoke_fire())

    os.makedirs(cache, exist_ok=True)
    ds.cache_directory = cache  # last: changing settings afterwards deletes the cache
    bpy.ops.wm.save_as_mainfile(filepath=out)
    if bake:
        bpy.context.view_layer.objects.active = do
        do.select_set(True)
        t0 = time.time()
        res = bpy.ops.fluid.bake_all()
        print(f'bake {res} in {time.time() - t0:.1f} s -> {cache}')
        bpy.ops.wm.save_as_mainfile(filepath=out)
    print('built', out)


if __name__ == '__main__':
    main()
    sys.stdout.flush()
    if bpy.app.version >= (4, 0, 0):
        os._exit(0)
