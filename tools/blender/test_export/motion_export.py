"""The exporter's motion blur: turn Motion Blur on in FILE.blend (build_scene.py's
main.blend), give its Volume object velocity settings, export it twice
(--fluid-velocity blender and physical) and check what the scene files say.
Prints MOTION_OK when every check held.

    VENV/bin/python tools/blender/test_export/motion_export.py FILE.blend DIR

Checks:
- [render] motion_blur, shutter, shutter_position, fps (fps / fps_base);
- the Volume object's velocity_scale and velocity_unit, with a warning that
  Blender ignores the shutter for velocities per frame;
- each domain's velocity_scale: with 'blender', the per-axis scale k with
  T3 . diag(k) = M3, T3 the exported transform's linear part and M3 the
  domain object's (Cycles reads the cache vector in the domain object's
  space); with 'physical', 2.5 x time_scale x voxel (Mantaflow's cells per
  time unit, a frame being 0.1 x 25 / fps x time_scale units).
"""
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import vdbphoton_export  # noqa: E402  (tools/blender/vdbphoton_export.py)

try:
    import tomllib
except ImportError:  # Python < 3.11
    tomllib = None


def close(a, b, tol, what):
    assert abs(a - b) <= tol * max(1.0, abs(b)), f'{what}: {a} against {b}'


def check(blend, out_dir):
    bpy.ops.wm.open_mainfile(filepath=blend)
    sc = bpy.context.scene
    r = sc.render
    r.use_motion_blur = True
    r.motion_blur_shutter = 0.3
    r.motion_blur_position = 'START'
    r.fps = 30
    r.fps_base = 1.001
    cloud = next(o for o in sc.objects if o.type == 'VOLUME')
    cloud.data.velocity_scale = 2.0
    cloud.data.velocity_unit = 'FRAME'
    domains = [o for o in sc.objects for m in o.modifiers
               if m.type == 'FLUID' and m.fluid_type == 'DOMAIN']
    assert domains, 'no fluid domain in the scene'
    docs = {}
    for mode in ('blender', 'physical'):
        warnings = []
        path = os.path.join(out_dir, f'motion_{mode}.toml')
        vdbphoton_export.export_scene(path, sc, None, frames='25', fluid_velocity=mode,
                                      warn=lambda kind, m: warnings.append((kind, m)))
        with open(path, 'rb') as f:
            docs[mode] = tomllib.loads(f.read().decode('utf-8'))
        assert any(k == 'warning' and 'ignores the shutter for velocities per frame' in m
                   for k, m in warnings), f'no warning about Frame units: {warnings}'
    doc = docs['blender']
    rd = doc['render']
    assert rd['motion_blur'] is True, rd
    close(rd['shutter'], 0.3, 1e-6, 'shutter')
    assert rd['shutter_position'] == 'start', rd
    close(rd['fps'], 30 / 1.001, 1e-6, 'fps')
    vols = doc['volume']
    cv = next(v for v in vols if 'cloud' in v['file'])
    close(cv['velocity_scale'], 2.0, 1e-6, 'cloud velocity_scale')
    assert cv['velocity_unit'] == 'frame', cv
    ndom = 0
    for o in domains:
        ds = next(m for m in o.modifiers if m.type == 'FLUID').domain_settings
        cache = os.path.normpath(bpy.path.abspath(ds.cache_directory))
        pick = [i for i, v in enumerate(vols) if v['file'].startswith(cache)]
        if not pick:
            continue
        i = pick[0]
        v = vols[i]
        k = v['velocity_scale']
        assert isinstance(k, list) and len(k) == 3, v
        rows = v['transform']['matrix']
        m3 = o.matrix_world.to_3x3()
        for a in range(3):
            for b in range(3):
                # (T3 . diag(k))[a][b] = T3[a][b] k[b]
                close(rows[a][b] * k[b], m3[a][b] * ds.velocity_scale, 1e-5,
                      f"{o.name}: (T3 diag(k))[{a}][{b}]")
        kp = docs['physical']['volume'][i]['velocity_scale']
        # The cache's voxel, from the file.
        info = vdbphoton_export.Exporter(sc).grid_info(
            vdbphoton_export.pattern_path(v['file'], 25 + v.get('frame_offset', 0)))
        dx = info[2]['density'].to_3x3().to_scale()[0]
        close(kp, 2.5 * ds.time_scale * dx * ds.velocity_scale, 1e-6,
              f'{o.name}: physical velocity_scale')
        ndom += 1
    assert ndom >= 1, 'no domain was exported'


try:
    check(sys.argv[1], sys.argv[2])
except Exception as e:  # noqa: BLE001 (any failure fails the test)
    print(f'motion_export: {type(e).__name__}: {e}', file=sys.stderr, flush=True)
    os._exit(1)
print('MOTION_OK', flush=True)
# As vdbphoton_export.py does: leave without the bpy module's teardown.
os._exit(0)
