"""Render a test scene with Blender 5.0.1 Cycles (bpy module).

For vdbphoton scene files (TOML/JSON, docs/scene.md) use
tools/blender/render_cycles.py instead; this script reads its own small JSON
format and is kept for the white diffuse plane the scene format lacks.

Usage: VENV/bin/python scripts/cycles_render.py CONFIG.json OUT.exr
(VENV: a Python 3.11 venv with `pip install bpy==5.0.1`). Paths in CONFIG
are relative to the config file. Example: scripts/cycles/spot_cloud.json,
the same scene as scripts/cycles/spot_cloud.toml for vdbphoton (Blender's
light power P in W is an intensity of P/(4 pi) W/sr: 376.99 W = 30 W/sr).

CONFIG keys:
  width, height, spp, seed, max_bounces
  camera: {position, look_at, vfov}  or  {ortho: true, position, look_at, ortho_scale}
  lights: list of {type: point|spot|sun, ...}
     point: position, power (W)
     spot:  position, direction (axis into scene), power (W), cone_angle (deg, full), blend
     sun:   direction (towards light), strength (W/m^2), angle (deg)
  plane: {size, albedo}    optional white diffuse plane at z=0
  volume: {file, density, color, anisotropy}   optional Principled Volume
  soft_falloff: bool (default False), radius: light radius (default 0)
Settings follow shared/data/reference/README.md (unbiased Cycles: no
clamping, adaptive sampling, light tree, guiding or denoising; box filter;
full volume precision, no volume clipping).
"""
import json
import math
import sys
import time

import bpy
from mathutils import Vector

import os

cfg_path = os.path.abspath(sys.argv[1])
cfg = json.load(open(cfg_path))
out = os.path.abspath(sys.argv[2])

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = 'CYCLES'
cy = scene.cycles
cy.device = 'CPU'
cy.samples = cfg.get('spp', 64)
cy.seed = cfg.get('seed', 0)
cy.use_adaptive_sampling = False
cy.use_denoising = False
cy.use_light_tree = False
cy.light_sampling_threshold = 0.0
cy.sample_clamp_direct = 0.0
cy.sample_clamp_indirect = 0.0
cy.use_guiding = False
cy.pixel_filter_type = 'BOX'
cy.filter_width = 1.0
mb = cfg.get('max_bounces', 256)
cy.max_bounces = mb
cy.volume_bounces = mb
cy.diffuse_bounces = mb
cy.glossy_bounces = mb
cy.transmission_bounces = mb
cy.transparent_max_bounces = 1024
cy.caustics_reflective = True
cy.caustics_refractive = True
cy.blur_glossy = 0.0
scene.render.threads_mode = 'FIXED'
scene.render.threads = 2
scene.render.resolution_x = cfg['width']
scene.render.resolution_y = cfg['height']
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
scene.view_settings.view_transform = 'Standard'
scene.view_settings.look = 'None'
scene.view_settings.exposure = 0.0
scene.view_settings.gamma = 1.0
scene.render.image_settings.file_format = 'OPEN_EXR'
scene.render.image_settings.color_depth = '32'
scene.render.image_settings.color_mode = 'RGBA'
scene.render.image_settings.exr_codec = 'ZIP'
scene.render.filepath = out

# World: black
world = bpy.data.worlds.new('World')
world.use_nodes = True
bg = world.node_tree.nodes['Background']
bg.inputs['Color'].default_value = (0, 0, 0, 1)
bg.inputs['Strength'].default_value = 0.0
scene.world = world

# Camera
c = cfg['camera']
cam = bpy.data.cameras.new('Cam')
cam.sensor_fit = 'VERTICAL'
if c.get('ortho'):
    cam.type = 'ORTHO'
    cam.ortho_scale = c['ortho_scale']
else:
    cam.type = 'PERSP'
    cam.angle_y = math.radians(c.get('vfov', 40.0))
cam.clip_start = 0.01
cam.clip_end = 1000.0
camo = bpy.data.objects.new('Cam', cam)
scene.collection.objects.link(camo)
pos = Vector(c['position'])
camo.location = pos
d = Vector(c['look_at']) - pos
camo.rotation_mode = 'QUATERNION'
camo.rotation_quaternion = d.to_track_quat('-Z', 'Y')
scene.camera = camo

# Lights
for i, L in enumerate(cfg.get('lights', [])):
    t = L['type']
    ld = bpy.data.lights.new(f'L{i}', type=t.upper())
    lo = bpy.data.objects.new(f'L{i}', ld)
    scene.collection.objects.link(lo)
    lo.rotation_mode = 'QUATERNION'
    ld.color = (1, 1, 1)
    if t in ('point', 'spot'):
        lo.location = Vector(L['position'])
        ld.energy = L['power']
        ld.shadow_soft_size = L.get('radius', cfg.get('radius', 0.0))
        if hasattr(ld, 'use_soft_falloff'):
            ld.use_soft_falloff = L.get('soft_falloff', cfg.get('soft_falloff', False))
        if t == 'spot':
            ld.spot_size = math.radians(L['cone_angle'])
            ld.spot_blend = L['blend']
            ld.show_cone = False
            lo.rotation_quaternion = Vector(L['direction']).to_track_quat('-Z', 'Y')
    elif t == 'sun':
        ld.energy = L['strength']
        ld.angle = math.radians(L.get('angle', 0.0))
        # Blender's sun shines along its local -Z; scene direction points towards the light
        lo.rotation_quaternion = (-Vector(L['direction'])).to_track_quat('-Z', 'Y')
    else:
        raise SystemExit('unknown light ' + t)

def empty_material(name):
    """A node material with no nodes, to build the shader from scratch."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    return m, nt


# Plane
if 'plane' in cfg:
    p = cfg['plane']
    bpy.ops.mesh.primitive_plane_add(size=p.get('size', 20.0), location=(0, 0, 0))
    po = bpy.context.active_object
    m, nt = empty_material('White')
    dif = nt.nodes.new('ShaderNodeBsdfDiffuse')
    a = p.get('albedo', 1.0)
    dif.inputs['Color'].default_value = (a, a, a, 1)
    dif.inputs['Roughness'].default_value = 0.0
    o = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(dif.outputs['BSDF'], o.inputs['Surface'])
    po.data.materials.append(m)

# Volume
if 'volume' in cfg:
    v = cfg['volume']
    vol = bpy.data.volumes.new('cloud')
    vol.filepath = os.path.join(os.path.dirname(cfg_path), v['file'])
    vol.render.precision = 'FULL'
    vol.render.clipping = 0.0
    vo = bpy.data.objects.new('cloud', vol)
    scene.collection.objects.link(vo)
    m, nt = empty_material('Vol')
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    pv.inputs['Density'].default_value = v['density']
    col = v['color']
    pv.inputs['Color'].default_value = (col, col, col, 1)
    pv.inputs['Anisotropy'].default_value = v['anisotropy']
    pv.inputs['Absorption Color'].default_value = (0, 0, 0, 1)
    o = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(pv.outputs['Volume'], o.inputs['Volume'])
    m.cycles.volume_interpolation = 'LINEAR'
    vo.data.materials.append(m)
    vol.grids.load()
    print('grids:', [g.name for g in vol.grids], 'density attr input:',
          [s.name for s in pv.inputs])

print("SAMPLES", cy.samples, "THREADS", scene.render.threads)
t0 = time.time()
bpy.ops.render.render(write_still=True)
print(f'RENDER_WALL {time.time() - t0:.2f} s -> {out}')
