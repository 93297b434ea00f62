"""Issue 50's shots against Cycles 5.0.1: surfaces shaded as Cycles shades
them. Builds them in Blender 5.0.1 (the `bpy` module), renders Cycles'
references, and exports our versions through the exporter.

Usage (from the repository's root, VENV a Python 3.11 venv with bpy 5.0.1):

    VENV/bin/python tools/blender/test_export/build_surface_shot.py render SHOT VARIANT OUT.exr \
        [--vdb VDB] --spp N --seed S [--threads 2]
    VENV/bin/python tools/blender/test_export/build_surface_shot.py export SHOT OUT.toml \
        [--vdb VDB] [--relative-vdb PATH] [--blend OUT.blend]

VDB (shot `smoke` only) is the Blender smoke frame,
shared/data/blender_smoke/fluid_data_0025.vdb.

SHOT `smoke`: the smoke + fire frame 25 over a ground plane with a ball, a
sun and a sky, everything shaded as an artist leaves it (no shadow catcher,
no holdout, film opaque). Camera, sun and smoke as issue 49's shot
(build_mesh_shot.py, tests/data/cycles/smoke25_shot.toml):
  smoke     a Volume object reading VDB, translated by (-1.25, -1.25, -1.25),
            Space World, Blender's Quick Smoke fire material as
            smoke25_sun.toml has it (Principled Volume: Density 5 x
            `density`, Color 0.5, Absorption Color 0, Anisotropy 0,
            Blackbody Intensity 1, Temperature 1000 K x the cache's
            `temperature` grid).
  ground    a 40 x 40 plane (one quad) at z = -0.40, a Principled BSDF with
            Base Color GROUND_COLOUR, Roughness GROUND_ROUGHNESS, the rest
            Blender's defaults (Metallic 0, IOR 1.5, Specular IOR Level 0.5).
  ball      a smooth-shaded UV sphere of radius 0.28 (48 x 24 segments) at
            BALL_CENTRE, in front of the plume's base: a Principled BSDF
            with Base Color BALL_COLOUR, Roughness BALL_ROUGHNESS, every ray
            type on (it shadows the ground and the smoke, and reflects).
  sun       irradiance SUN_IRRADIANCE from SUN_DIRECTION, angle 0.
  world     a constant sky SMOKE_SKY.
  camera    at CAMERA['position'] looking at CAMERA['look_at'], vertical
            field of view 36 degrees, 200 x 150.

SHOT `spheres`: three smooth-shaded Principled spheres (radius 0.5, 64 x 32
segments; one mesh, each object's material linked to the object) in a row,
under a sun and a constant sky, nothing else:
  Rough     a rough dielectric: Base Color (0.8, 0.3, 0.2), Roughness 0.8
  Glossy    a glossy dielectric: Base Color (0.1, 0.25, 0.6), Roughness 0.15
  Metal     a metal: Base Color (0.95, 0.7, 0.35), Metallic 1, Roughness 0.3
  (the rest of each Blender's defaults: IOR 1.5, Specular IOR Level 0.5,
  Specular Tint white); sun SPHERES_SUN from SPHERES_SUN_DIRECTION, angle 0;
  sky SPHERES_SKY; camera SPHERES_CAMERA, 200 x 150.

SHOT `texture`: image textures through UVs, with a closed form. Two 1.6 x
1.6 quads side by side facing the camera, each with a UV map from (0, 0) at
its lower left to (1, 1) at its upper right, under a uniform white sky
(radiance 1) and nothing else, so that each pixel's radiance is the
texture's linear value there (a Lambertian surface under a uniform sky of
radiance 1 reflects its albedo): `sRGB quad` (left) a Diffuse BSDF whose
Color is an Image Texture of TEXTURE (8 x 4 texels, sRGB), `Linear quad`
(right) the same image read as Non-Color, through a UV Map node; Linear
interpolation, Repeat. The image is packed in the .blend (the exporter
writes it beside the PLYs); camera at (0, -4, 0) looking at +Y, vfov 30
degrees, 128 x 64.

All: Cycles 5.0.1 with render_cycles.py's unbiased settings (CPU, no
clamping, no adaptive sampling, light tree, path guiding or denoising,
light threshold 0, box filter 1 px, unbiased volumes, volume precision
FULL, caustics on, Filter Glossy 0), every bounce limit 127 = vdbphoton's
max_bounces 128.

VARIANT (render):
  full        the shot (both shots).
  nofire      smoke: the smoke's blackbody off (Blackbody Intensity 0), to
              see where the fire lights the ground.
  nosmoke     smoke: the smoke hidden from render (the ground's light
              without the plume).
  smokealpha  smoke: the smoke alone (ground and ball hidden), film
              transparent: its alpha says where the smoke is in front.
  nobounce    smoke: the ground black to every ray but the camera's (a Mix
              Shader on Light Path > Is Camera Ray): what the ground's
              bounced light adds to the smoke and the ball.
  mask        smoke: the smoke hidden, the ground an Emission of red 1 and
              the ball of green 1, the world black: which surface each
              pixel sees (fractions at edges).

export writes our version of the shot through vdbphoton_export.py (the
output render/surface_<shot>.exr without preview, vdbphoton's max_bounces
128; the meshes, with their materials, normals and UVs, into
'<stem>_meshes/' beside OUT.toml). --relative-vdb writes PATH (relative to
OUT.toml) as the volume's file instead of VDB's absolute path. --blend
saves the .blend it exported.

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
sys.path.insert(0, HERE)
import render_cycles  # noqa: E402  (tools/blender/render_cycles.py)
import vdbphoton_export  # noqa: E402  (tools/blender/vdbphoton_export.py)
from build_mesh_shot import (BALL_CENTRE, BALL_RADIUS, CAMERA, GROUND_Z, SMOKE,  # noqa: E402
                             SUN_DIRECTION, SUN_IRRADIANCE, means)

WIDTH, HEIGHT = 200, 150
MAX_BOUNCES = 128
SMOKE_SKY = [0.05, 0.06, 0.08]
GROUND_COLOUR = (0.25, 0.25, 0.25)
GROUND_ROUGHNESS = 0.7
BALL_COLOUR = (0.7, 0.25, 0.15)
BALL_ROUGHNESS = 0.4

SPHERES = [
    ('Rough', (-1.15, 0.0, 0.0), {'Base Color': (0.8, 0.3, 0.2, 1.0), 'Roughness': 0.8}),
    ('Glossy', (0.0, 0.0, 0.0), {'Base Color': (0.1, 0.25, 0.6, 1.0), 'Roughness': 0.15}),
    ('Metal', (1.15, 0.0, 0.0), {'Base Color': (0.95, 0.7, 0.35, 1.0), 'Metallic': 1.0,
                                 'Roughness': 0.3}),
]
TEXTURE = 'surface_texture.png'
TEXTURE_SIZE = (8, 4)
TEXTURE_CAMERA = {'position': [0.0, -4.0, 0.0], 'look_at': [0.0, 0.0, 0.0],
                  'up': [0.0, 0.0, 1.0], 'vfov': 30.0}
SPHERES_SUN_DIRECTION = [0.5, -0.6, 0.62]
SPHERES_SUN = [2.5, 2.4, 2.2]
SPHERES_SKY = [0.12, 0.15, 0.2]
SPHERES_CAMERA = {'position': [0.0, -5.0, 1.0], 'look_at': [0.0, 0.0, 0.0],
                  'up': [0.0, 0.0, 1.0], 'vfov': 30.0}


def principled_surface(name, inputs):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    p = nt.nodes.new('ShaderNodeBsdfPrincipled')
    for k, v in inputs.items():
        p.inputs[k].default_value = v
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(p.outputs['BSDF'], out.inputs['Surface'])
    return m


def uv_sphere(name, u, v, r):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=u, v_segments=v, radius=r, calc_uvs=True)
    bm.to_mesh(me)
    bm.free()
    for p in me.polygons:
        p.use_smooth = True
    return me


def base(spp, seed, threads, vols, camera, sun_dir, sun, sky, size=(WIDTH, HEIGHT)):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    args = SimpleNamespace(width=None, height=None, spp=spp, seed=seed, threads=threads,
                           half=False)
    render_cycles.setup_render(sc, {'width': size[0], 'height': size[1], 'spp': spp,
                                    'seed': seed, 'max_bounces': MAX_BOUNCES}, args, vols)
    render_cycles.setup_camera(sc, camera)
    render_cycles.setup_lights(sc, [{'type': 'sun', 'direction': sun_dir,
                                     'irradiance': sun, 'angle': 0.0}])
    render_cycles.setup_world(sc, {'radiance': sky}, os.getcwd())
    sc.camera.name = 'Camera'
    bpy.data.objects['L0'].name = 'Sun'
    sc.frame_current = 1
    return sc


def build_smoke(vdb, spp=64, seed=0, threads=2):
    if not vdb:
        raise SystemExit('the smoke shot needs --vdb (shared/data/blender_smoke/'
                         'fluid_data_0025.vdb)')
    sc = base(spp, seed, threads, [SMOKE], CAMERA, SUN_DIRECTION, SUN_IRRADIANCE, SMOKE_SKY)
    render_cycles.setup_volume(sc, 0, dict(SMOKE, file=os.path.abspath(vdb)), os.getcwd(),
                               [], None)
    bpy.data.objects['vol0'].name = 'Smoke'

    gme = bpy.data.meshes.new('Ground')
    gme.from_pydata([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [], [(0, 1, 2, 3)])
    gme.materials.append(principled_surface('Ground', {
        'Base Color': GROUND_COLOUR + (1.0,), 'Roughness': GROUND_ROUGHNESS}))
    ground = bpy.data.objects.new('Ground', gme)
    ground.location = (0.0, 0.0, GROUND_Z)
    sc.collection.objects.link(ground)

    bme = uv_sphere('Ball', 48, 24, BALL_RADIUS)
    bme.materials.append(principled_surface('Ball', {
        'Base Color': BALL_COLOUR + (1.0,), 'Roughness': BALL_ROUGHNESS}))
    ball = bpy.data.objects.new('Ball', bme)
    ball.location = BALL_CENTRE
    sc.collection.objects.link(ball)
    return sc


def build_spheres(spp=64, seed=0, threads=2):
    sc = base(spp, seed, threads, [], SPHERES_CAMERA, SPHERES_SUN_DIRECTION, SPHERES_SUN,
              SPHERES_SKY)
    me = uv_sphere('Sphere', 64, 32, 0.5)
    me.materials.append(None)
    for name, at, inputs in SPHERES:
        o = bpy.data.objects.new(name, me)
        o.location = at
        sc.collection.objects.link(o)
        # One mesh (one PLY), each object its own material (slot linked to
        # the object).
        o.material_slots[0].link = 'OBJECT'
        o.material_slots[0].material = principled_surface(name, inputs)
    return sc


def texture_pixels():
    """TEXTURE's 8 x 4 RGBA texels, rows from the bottom (Blender's order):
    distinct in every texel and channel, so that a flip or a shift shows."""
    px = []
    for j in range(TEXTURE_SIZE[1]):
        for i in range(TEXTURE_SIZE[0]):
            px.append(((i + 0.5) / TEXTURE_SIZE[0], (j + 0.5) / TEXTURE_SIZE[1],
                       ((i * 3 + j * 5) % 8 + 0.5) / 8.0, 1.0))
    return px


def build_texture(spp=64, seed=0, threads=2):
    import tempfile
    sc = base(spp, seed, threads, [], TEXTURE_CAMERA, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0],
              [1.0, 1.0, 1.0], size=(128, 64))
    bpy.data.objects.remove(bpy.data.objects['Sun'])
    img = bpy.data.images.new(TEXTURE, *TEXTURE_SIZE, alpha=True)
    img.pixels = [x for p in texture_pixels() for x in p]
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, TEXTURE)
        img.filepath_raw = path
        img.file_format = 'PNG'
        img.save()
        bpy.data.images.remove(img)
        srgb = bpy.data.images.load(path)
        srgb.pack()
        srgb.filepath = '//' + TEXTURE
    srgb.colorspace_settings.name = 'sRGB'
    for name, x, space in (('sRGB quad', -0.9, 'sRGB'), ('Linear quad', 0.9, 'Non-Color')):
        me = bpy.data.meshes.new(name)
        me.from_pydata([(-0.8, 0, -0.8), (0.8, 0, -0.8), (0.8, 0, 0.8), (-0.8, 0, 0.8)], [],
                       [(0, 1, 2, 3)])
        uv = me.uv_layers.new(name='UVMap')
        for k, c in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]):
            uv.uv[k].vector = c
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        nt = m.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        d = nt.nodes.new('ShaderNodeBsdfDiffuse')
        t = nt.nodes.new('ShaderNodeTexImage')
        if space == 'sRGB':
            t.image = srgb
        else:
            t.image = srgb.copy()
            t.image.colorspace_settings.name = space
        t.interpolation = 'Linear'
        t.extension = 'REPEAT'
        u = nt.nodes.new('ShaderNodeUVMap')
        u.uv_map = 'UVMap'
        out = nt.nodes.new('ShaderNodeOutputMaterial')
        nt.links.new(u.outputs['UV'], t.inputs['Vector'])
        nt.links.new(t.outputs['Color'], d.inputs['Color'])
        nt.links.new(d.outputs['BSDF'], out.inputs['Surface'])
        me.materials.append(m)
        o = bpy.data.objects.new(name, me)
        o.location = (x, 0.0, 0.0)
        sc.collection.objects.link(o)
    return sc


def build(shot, vdb, spp=64, seed=0, threads=2):
    if shot == 'smoke':
        return build_smoke(vdb, spp, seed, threads)
    if shot == 'texture':
        return build_texture(spp, seed, threads)
    return build_spheres(spp, seed, threads)


def render(shot, vdb, variant, out, spp, seed, threads):
    variants = {'smoke': ('full', 'nofire', 'nosmoke', 'smokealpha', 'nobounce', 'mask'),
                'spheres': ('full',), 'texture': ('full',)}
    if variant not in variants[shot]:
        print(f"unknown variant {variant!r} of shot {shot!r} ({', '.join(variants[shot])})",
              file=sys.stderr)
        return 2
    sc = build(shot, vdb, spp, seed, threads)
    if variant == 'nofire':
        for n in bpy.data.materials['vol0'].node_tree.nodes:
            if n.bl_idname == 'ShaderNodeVolumePrincipled':
                n.inputs['Blackbody Intensity'].default_value = 0.0
    elif variant == 'nosmoke':
        bpy.data.objects['Smoke'].hide_render = True
    elif variant == 'smokealpha':
        bpy.data.objects['Ground'].hide_render = True
        bpy.data.objects['Ball'].hide_render = True
        sc.render.film_transparent = True
    elif variant == 'nobounce':
        nt = bpy.data.materials['Ground'].node_tree
        p = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeBsdfPrincipled'][0]
        out_n = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'][0]
        lp = nt.nodes.new('ShaderNodeLightPath')
        black = nt.nodes.new('ShaderNodeBsdfDiffuse')
        black.inputs['Color'].default_value = (0, 0, 0, 1)
        mix = nt.nodes.new('ShaderNodeMixShader')
        nt.links.new(lp.outputs['Is Camera Ray'], mix.inputs['Fac'])
        nt.links.new(black.outputs[0], mix.inputs[1])
        nt.links.new(p.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], out_n.inputs['Surface'])
    elif variant == 'mask':
        bpy.data.objects['Smoke'].hide_render = True
        sc.world.node_tree.nodes['Background'].inputs['Color'].default_value = (0, 0, 0, 1)
        for name, col in (('Ground', (1, 0, 0, 1)), ('Ball', (0, 1, 0, 1))):
            nt = bpy.data.materials[name].node_tree
            for n in list(nt.nodes):
                if n.bl_idname == 'ShaderNodeBsdfPrincipled':
                    nt.nodes.remove(n)
            em = nt.nodes.new('ShaderNodeEmission')
            em.inputs['Color'].default_value = col
            out_n = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'][0]
            nt.links.new(em.outputs[0], out_n.inputs['Surface'])
    out = os.path.abspath(out)
    r = sc.render
    print(f'{shot} {variant}: {r.resolution_x}x{r.resolution_y}, {spp} spp, seed {seed}, '
          f'{threads} threads', flush=True)
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


def export(shot, vdb, out, relative_vdb, blend):
    sc = build(shot, vdb)
    out = os.path.abspath(out)
    if blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(blend))

    def warn(kind, m):
        print(f'vdbphoton_export: {kind}: {m}', file=sys.stderr, flush=True)

    ex = vdbphoton_export.export_scene(out, sc, sc.view_layers[0], warn=warn,
                                       output=f'render/surface_{shot}.exr', no_preview=True)
    text = open(out).read()
    if relative_vdb:
        text = text.replace(os.path.abspath(vdb), relative_vdb)
    what = {'smoke': "the Blender smoke + fire frame 25 (placed and shaded as smoke25_sun.toml)\n"
                     "# over a grey Principled ground with a Principled ball, a sun and a sky, "
                     "film opaque",
            'spheres': "three Principled spheres (rough dielectric, glossy dielectric, metal)\n"
                       "# under a sun and a constant sky",
            'texture': "two quads with an image texture through their UV map (sRGB and\n"
                       "# Non-Color), diffuse under a uniform white sky: each pixel is the texture's "
                       "linear value"}[shot]
    head = (f"# Issue 50's shot against Cycles 5.0.1: {what}. Made by\n"
            "# tools/blender/test_export/build_surface_shot.py (export); see README.md.\n")
    with open(out, 'w') as f:
        f.write(head + text)
    print(f'wrote {out} ({len(ex.warnings)} warnings)')
    return 0


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument('mode', choices=['render', 'export'])
    ap.add_argument('shot', choices=['smoke', 'spheres', 'texture'])
    ap.add_argument('rest', nargs='+')
    ap.add_argument('--vdb')
    ap.add_argument('--spp', type=int, default=64)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--relative-vdb')
    ap.add_argument('--blend')
    a = ap.parse_args(argv)
    if a.mode == 'render':
        if len(a.rest) != 2:
            ap.error('render SHOT VARIANT OUT.exr')
        return render(a.shot, a.vdb, a.rest[0], a.rest[1], a.spp, a.seed, a.threads)
    if len(a.rest) != 1:
        ap.error('export SHOT OUT.toml')
    return export(a.shot, a.vdb, a.rest[0], a.relative_vdb, a.blend)


if __name__ == '__main__':
    code = main(sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
