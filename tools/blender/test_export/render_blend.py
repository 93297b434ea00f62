"""Render a .blend with Blender 5.0.1 Cycles (the `bpy` module) as a
reference for vdbphoton: the scene's own camera, lights, world, objects,
materials, resolution and bounce limits, with every setting that would bias
a reference off (render_cycles.py's list, /work/shared/REFERENCE.md): CPU;
clamping 0; adaptive sampling, light tree, path guiding, denoising off;
light threshold 0; box filter 1 px; unbiased volume integrator; Volume
objects at FULL precision, clipping 0; Standard view, no look/exposure;
dither 0. Motion blur as the .blend has it (Render Properties > Motion
Blur), with Cycles' ray-marching volume integrator at a quarter of the
default step when it is on (its default integrator cuts smears off where
the volume is empty at the middle of the shutter: render_cycles.py's
setup_motion_blur).

Usage:
    VENV/bin/python tools/blender/test_export/render_blend.py FILE.blend OUT.exr \
        --frame F --spp N [--seed S] [--threads 2] [--substitute-domains]

Smoke domains: with manta_fix.py the bpy module reads the Mantaflow cache
and Cycles renders the domain itself; the script checks that the domain's
density was read and prints `CYCLES_DOMAIN real NAME` (with ` fire flame
max F` when Blender gave the domain fire and its flame grid was read, or
` no fire`). Blender gives a domain fire only when a Fire or Fire + Smoke
flow takes part (or the cache's config says so); then its `temperature`
attribute is made from the flame grid. If reading fails (or with
--substitute-domains), the domain is replaced by a Volume object reading
the same cache file, placed as Blender places a domain's voxels (voxel i at
local p0 + (i + 0.5) * cell, cell = local size / resolution), and the
script prints `CYCLES_DOMAIN substitute NAME`: it samples the cache's own
grids, so its `temperature` is the cache's grid, not Blender's (fire
differs).

Prints RENDER_TIME and exits 0 when OUT.exr is written.
"""
import argparse
import math
import os
import struct
import sys
import time

import bpy
from mathutils import Matrix

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import render_cycles  # noqa: E402  (tools/blender/render_cycles.py)


def f32(x):
    return struct.unpack('f', struct.pack('f', x))[0]


def unbiased(sc, spp, seed, threads, out):
    # render_cycles.py's unbiased settings; the scene keeps its own bounce
    # limits, image size and motion blur.
    blur = sc.render.use_motion_blur
    render_cycles.unbiased_cycles(sc, spp, seed, threads)
    r = sc.render
    if blur:
        r.use_motion_blur = True
        sc.cycles.volume_biased = True
        sc.cycles.volume_step_rate = 0.25
        sc.cycles.volume_max_steps = 4096
    r.use_border = False
    r.filepath = out
    for v in bpy.data.volumes:
        v.render.precision = 'FULL'
        v.render.clipping = 0.0
    for m in bpy.data.materials:
        m.cycles.volume_interpolation = 'LINEAR'


def gas_domains(sc):
    out = []
    for o in sc.objects:
        for mod in o.modifiers:
            if mod.type == 'FLUID' and mod.fluid_type == 'DOMAIN' and \
                    mod.domain_settings.domain_type == 'GAS':
                out.append((o, mod))
    return out


def domain_loaded(sc, o):
    """(density read, maximum of the flame grid or None without fire)."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = o.evaluated_get(dg)
    for mod in ev.modifiers:
        if mod.type == 'FLUID' and mod.fluid_type == 'DOMAIN':
            ds = mod.domain_settings
            d = ds.density_grid
            f = ds.flame_grid
            flame = max(f) if len(f) > 0 and max(f) > 0.0 else None
            return len(d) > 0 and max(d) > 0.0, flame
    return False, None


def substitute(sc, o, mod, frame):
    """A Volume object at the domain's voxels (non-adaptive domain)."""
    ds = mod.domain_settings
    cache = bpy.path.abspath(ds.cache_directory)
    path = os.path.join(cache, 'data', f'fluid_data_{frame - ds.cache_frame_offset:04d}.vdb')
    vs = [v.co for v in o.data.vertices]
    lo = [min(f32(v[i]) for v in vs) for i in range(3)]
    hi = [max(f32(v[i]) for v in vs) for i in range(3)]
    size = [f32(hi[i] - lo[i]) for i in range(3)]
    world = [abs(f32(size[i] * f32(o.scale[i]))) for i in range(3)]
    a = max(range(3), key=lambda i: (world[i], -i))
    res = [ds.resolution_max if i == a else
           max(int(f32(f32(world[i] * f32(ds.resolution_max / world[a])) + 0.5)), 4)
           for i in range(3)]
    vol = bpy.data.volumes.new(o.name + ' cache')
    vol.filepath = path
    vol.render.precision = 'FULL'
    vol.render.clipping = 0.0
    vol.grids.load()
    index_to_file = Matrix(vol.grids['density'].matrix_object)
    index_to_local = Matrix.Identity(4)
    for i in range(3):
        cell = size[i] / res[i]
        index_to_local[i][i] = cell
        index_to_local[i][3] = lo[i] + 0.5 * cell
    vo = bpy.data.objects.new(o.name + ' cache', vol)
    sc.collection.objects.link(vo)
    vo.matrix_world = o.matrix_world @ index_to_local @ index_to_file.inverted()
    for m in o.data.materials:
        vol.materials.append(m)
    o.hide_render = True
    return vo


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument('blend')
    ap.add_argument('out')
    ap.add_argument('--frame', type=int, required=True)
    ap.add_argument('--spp', type=int, required=True)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--substitute-domains', action='store_true')
    a = ap.parse_args(argv)
    fixed = False
    if not a.substitute_domains:
        try:
            import manta_fix
            fixed = manta_fix.fix()
        except Exception as e:  # noqa: BLE001
            print(f'manta_fix failed: {e}')
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(a.blend), load_ui=False)
    sc = bpy.context.scene
    unbiased(sc, a.spp, a.seed, a.threads, os.path.abspath(a.out))
    sc.frame_set(a.frame)
    for o, mod in gas_domains(sc):
        loaded, flame = domain_loaded(sc, o) if fixed else (False, None)
        if loaded:
            fire = 'no fire' if flame is None else f'fire flame max {flame:.6g}'
            print(f"CYCLES_DOMAIN real '{o.name}' {fire}")
        else:
            substitute(sc, o, mod, a.frame)
            print(f"CYCLES_DOMAIN substitute '{o.name}'")
    sc.frame_set(a.frame)
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    print(f'RENDER_TIME {time.time() - t0:.2f} s -> {a.out}')
    return 0 if os.path.isfile(a.out) else 1


if __name__ == '__main__':
    code = main(sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
