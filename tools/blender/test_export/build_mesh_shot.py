"""The shot of issue 49's check "Against Cycles 5.0.1": the Blender smoke +
fire frame 25 over a ground plane, a ball in front of part of the plume and
a sun that makes the plume cast its shadow on the ground. Builds it in
Blender 5.0.1 (the `bpy` module), renders Cycles' references of it, and
exports our version of it through the exporter.

Usage (from the repository's root, VENV a Python 3.11 venv with bpy 5.0.1):

    VENV/bin/python tools/blender/test_export/build_mesh_shot.py VDB render VARIANT OUT.exr \
        --spp N --seed S [--threads 2]
    VENV/bin/python tools/blender/test_export/build_mesh_shot.py VDB export OUT.toml \
        [--relative-vdb PATH] [--blend OUT.blend]

VDB is the Blender smoke frame, shared/data/blender_smoke/fluid_data_0025.vdb.

The shot (placed as tests/data/cycles/smoke25_sun.toml places the smoke):
  smoke     a Volume object reading VDB, translated by (-1.25, -1.25, -1.25)
            (the file's index (0,0,0) at the domain's corner), Space World,
            with Blender's Quick Smoke fire material as smoke25_sun.toml has
            it (Principled Volume: Density 5 x `density`, Color 0.5,
            Absorption Color 0, Anisotropy 0, Blackbody Intensity 1,
            Temperature 1000 K x the cache's `temperature` grid); it spans
            about x, y in [-0.76, 0.72], z in [-0.37, 1.49].
  ground    a 40 x 40 plane at z = -0.40, just under the smoke's lowest
            voxels. Its material is a grey Diffuse BSDF (albedo GROUND_ALBEDO)
            for camera rays and black for every other ray (a Mix Shader on
            Light Path > Is Camera Ray): the ground shows the sun's, the
            sky's, the smoke's and the fire's light as Cycles computes it,
            but bounces nothing back into the smoke. That bounce is the next
            issue's (surfaces lit and lighting as Cycles does): with a
            plain diffuse ground it makes the smoke 10-12 % brighter
            (REFERENCE.md), beyond the check's 2 %. A black surface that
            occludes is what vdbphoton's unshaded meshes are to the rays
            that do not come from the camera.
  ball      a UV sphere of radius 0.28 (48 x 24 segments: 2,208 triangles)
            at BALL_CENTRE, between the camera and the plume's lower right.
            Its material is an Emission shader (Emission Sampling None)
            and it is visible to camera rays only (Ray Visibility: Shadow,
            Diffuse, Glossy, Transmission and Volume Scatter off): it looks
            the same with and without the smoke, casts no shadow and lights
            nothing, so the plate holds it once and exactly as the full
            render shows it (the brief asks for Shadow and Diffuse off; the
            rest keeps the smoke's and fire's light off it).
  sun       irradiance SUN_IRRADIANCE towards SUN_DIRECTION (from the right,
            a little in front, 41 degrees up), angle 0: the plume's shadow
            falls to the left on the ground, in the frame.
  world     a constant (0.03, 0.035, 0.045): seen directly above the ground's
            far edge.
  camera    at CAMERA['position'] looking at CAMERA['look_at'], vertical
            field of view 36 degrees, 200 x 150.
  render    Cycles 5.0.1 with render_cycles.py's unbiased settings (CPU,
            no clamping, adaptive sampling, light tree, path guiding or
            denoising; box filter 1 px; unbiased volumes; volume precision
            FULL; bounces 127 of every kind = vdbphoton's max_bounces 128).

VARIANT:
  full      everything, film opaque: the image our composite must match.
  plate     the geometry alone (the smoke hidden from render), film opaque.
  catcher   Cycles' own shadow-catcher render of the shot (ground Shadow
            Catcher, ball Holdout, Film Transparent, the view layer's Shadow
            Catcher pass): a multilayer EXR (ViewLayer.Combined.RGBA,
            ViewLayer.Shadow Catcher.RGB), for reference.

export writes our version of the shot through vdbphoton_export.py: the
ground a shadow catcher, the ball a holdout (its ray visibility as above),
Film Transparent, vdbphoton's max_bounces 128, the output
render/smoke25_shot.exr without preview; the meshes go into
'<stem>_meshes/' beside OUT.toml. --relative-vdb writes PATH (relative to
OUT.toml) as the volume's file instead of VDB's absolute path, so that the
scene stays usable in the repository. --blend saves the .blend it exported.

Prints RENDER_TIME (Cycles' render call) and the image's means.
"""
import argparse
import os
import sys
import time
from types import SimpleNamespace

import bpy
import bmesh

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import render_cycles  # noqa: E402  (tools/blender/render_cycles.py)
import vdbphoton_export  # noqa: E402  (tools/blender/vdbphoton_export.py)

WIDTH, HEIGHT = 200, 150
MAX_BOUNCES = 128
CAMERA = {'position': [-0.7, -5.6, 1.7], 'look_at': [-0.75, 0.3, 0.2], 'up': [0.0, 0.0, 1.0],
          'vfov': 36.0}
SUN_DIRECTION = [0.7, -0.25, 0.65]
SUN_IRRADIANCE = [3.0, 2.9, 2.7]
WORLD = [0.03, 0.035, 0.045]
GROUND_Z = -0.40
GROUND_ALBEDO = 0.25
BALL_CENTRE = (0.02, -1.1, 0.3)
BALL_RADIUS = 0.28
BALL_EMISSION = (0.16, 0.13, 0.10)
SMOKE = {'density_grid': 'density', 'temperature_grid': 'temperature',
         'transform': {'translate': [-1.25, -1.25, -1.25]},
         'material': {'density': 5.0, 'color': 0.5, 'absorption_color': 0.0,
                      'anisotropy': 0.0, 'blackbody_intensity': 1.0, 'temperature': 1000.0}}


def ground_material():
    """Grey diffuse for camera rays, black for all others."""
    m = bpy.data.materials.new('Ground')
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    lp = nt.nodes.new('ShaderNodeLightPath')
    black = nt.nodes.new('ShaderNodeBsdfDiffuse')
    black.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
    black.inputs['Roughness'].default_value = 0.0
    grey = nt.nodes.new('ShaderNodeBsdfDiffuse')
    grey.inputs['Color'].default_value = (GROUND_ALBEDO,) * 3 + (1.0,)
    grey.inputs['Roughness'].default_value = 0.0
    mix = nt.nodes.new('ShaderNodeMixShader')
    nt.links.new(lp.outputs['Is Camera Ray'], mix.inputs['Fac'])
    nt.links.new(black.outputs['BSDF'], mix.inputs[1])
    nt.links.new(grey.outputs['BSDF'], mix.inputs[2])
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(mix.outputs['Shader'], out.inputs['Surface'])
    return m


def ball_material():
    """Unlit: an Emission shader that lights nothing."""
    m = bpy.data.materials.new('Ball')
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    em = nt.nodes.new('ShaderNodeEmission')
    em.inputs['Color'].default_value = BALL_EMISSION + (1.0,)
    em.inputs['Strength'].default_value = 1.0
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(em.outputs['Emission'], out.inputs['Surface'])
    m.cycles.emission_sampling = 'NONE'
    return m


def build(vdb, spp=64, seed=0, threads=2):
    """The shot in a fresh scene (film opaque, no catcher, no holdout)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    args = SimpleNamespace(width=None, height=None, spp=spp, seed=seed, threads=threads,
                           half=False)
    render_cycles.setup_render(sc, {'width': WIDTH, 'height': HEIGHT, 'spp': spp,
                                    'seed': seed, 'max_bounces': MAX_BOUNCES}, args,
                               [SMOKE])
    render_cycles.setup_camera(sc, CAMERA)
    render_cycles.setup_lights(sc, [{'type': 'sun', 'direction': SUN_DIRECTION,
                                     'irradiance': SUN_IRRADIANCE, 'angle': 0.0}])
    render_cycles.setup_world(sc, {'radiance': WORLD}, os.getcwd())
    notes = []
    render_cycles.setup_volume(sc, 0, dict(SMOKE, file=os.path.abspath(vdb)), os.getcwd(),
                               notes, None)
    smoke = bpy.data.objects['vol0']
    smoke.name = 'Smoke'
    sc.camera.name = 'Camera'
    bpy.data.objects['L0'].name = 'Sun'

    gme = bpy.data.meshes.new('Ground')
    gme.from_pydata([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [], [(0, 1, 2, 3)])
    gme.materials.append(ground_material())
    ground = bpy.data.objects.new('Ground', gme)
    ground.location = (0.0, 0.0, GROUND_Z)
    sc.collection.objects.link(ground)

    bme = bpy.data.meshes.new('Ball')
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=BALL_RADIUS)
    bm.to_mesh(bme)
    bm.free()
    for p in bme.polygons:
        p.use_smooth = True
    bme.materials.append(ball_material())
    ball = bpy.data.objects.new('Ball', bme)
    ball.location = BALL_CENTRE
    for k in ('shadow', 'diffuse', 'glossy', 'transmission', 'volume_scatter'):
        setattr(ball, 'visible_' + k, False)
    sc.collection.objects.link(ball)
    sc.frame_current = 1
    return sc


def as_ours(sc):
    """The flags of our version (and of Cycles' shadow-catcher render)."""
    bpy.data.objects['Ground'].is_shadow_catcher = True
    bpy.data.objects['Ball'].is_holdout = True
    sc.render.film_transparent = True


def means(path):
    """Image mean (R, G, B) of an EXR's RGB, through OpenImageIO (bundled
    with bpy)."""
    import numpy as np
    oiio_dir = os.path.join(bpy.utils.resource_path('LOCAL'), 'python', 'lib',
                            f'python{sys.version_info[0]}.{sys.version_info[1]}', 'site-packages')
    if oiio_dir not in sys.path:
        sys.path.append(oiio_dir)
    try:
        import OpenImageIO as oiio
    except ImportError:
        return None
    inp = oiio.ImageInput.open(path)
    px = np.asarray(inp.read_image('float'))
    inp.close()
    rgb = px[..., :3].reshape(-1, 3).astype(np.float64).mean(axis=0)
    return float(rgb.mean()), [float(x) for x in rgb]


def render(vdb, variant, out, spp, seed, threads):
    sc = build(vdb, spp, seed, threads)
    if variant == 'plate':
        bpy.data.objects['Smoke'].hide_render = True
    elif variant == 'catcher':
        as_ours(sc)
        vl = sc.view_layers[0]
        vl.cycles.use_pass_shadow_catcher = True
        im = sc.render.image_settings
        if hasattr(im, 'media_type'):  # Blender 5
            im.media_type = 'MULTI_LAYER_IMAGE'
        im.file_format = 'OPEN_EXR_MULTILAYER'
        im.color_depth = '32'
        im.exr_codec = 'ZIP'
        sc.render.use_compositing = False
    elif variant != 'full':
        print(f'unknown variant {variant!r} (full, plate, catcher)', file=sys.stderr)
        return 2
    out = os.path.abspath(out)
    print(f'{variant}: {WIDTH}x{HEIGHT}, {spp} spp, seed {seed}, {threads} threads', flush=True)
    t0 = time.time()
    bpy.ops.render.render(write_still=False)
    t = time.time() - t0
    render_cycles.save_exr(sc, out)
    print(f'RENDER_TIME {t:.2f} s -> {out}')
    m = means(out)
    if m is not None:
        print(f'MEAN {m[0]:.7g} RGB {m[1][0]:.7g} {m[1][1]:.7g} {m[1][2]:.7g}')
    print(f"Saved: '{out}'", flush=True)
    return 0


def export(vdb, out, relative_vdb, blend):
    sc = build(vdb)
    as_ours(sc)
    out = os.path.abspath(out)
    if blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(blend))

    def warn(kind, m):
        print(f'vdbphoton_export: {kind}: {m}', file=sys.stderr, flush=True)

    vdbphoton_export.export_scene(out, sc, sc.view_layers[0], warn=warn,
                                  output='render/smoke25_shot.exr', no_preview=True)
    text = open(out).read()
    if relative_vdb:
        text = text.replace(os.path.abspath(vdb), relative_vdb)
    head = ("# Issue 49's shot against Cycles 5.0.1: the Blender smoke + fire frame 25 (placed and\n"
            "# shaded as smoke25_sun.toml), a ground plane as shadow catcher, a holdout ball in\n"
            "# front of the plume, film transparent. Made by\n"
            "# tools/blender/test_export/build_mesh_shot.py (export); see README.md.\n")
    with open(out, 'w') as f:
        f.write(head + text)
    print(f'wrote {out}')
    return 0


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument('vdb')
    ap.add_argument('mode', choices=['render', 'export'])
    ap.add_argument('rest', nargs='+')
    ap.add_argument('--spp', type=int, default=64)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--relative-vdb')
    ap.add_argument('--blend')
    a = ap.parse_args(argv)
    if a.mode == 'render':
        if len(a.rest) != 2:
            ap.error('render VARIANT OUT.exr')
        return render(a.vdb, a.rest[0], a.rest[1], a.spp, a.seed, a.threads)
    if len(a.rest) != 1:
        ap.error('export OUT.toml')
    return export(a.vdb, a.rest[0], a.relative_vdb, a.blend)


if __name__ == '__main__':
    code = main(sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
