"""Render a vdbphoton scene file with Blender 5.0.1 Cycles (the `bpy` module).

Usage:
    VENV/bin/python tools/blender/render_cycles.py SCENE.toml OUT.exr \
        [--spp N] [--seed S] [--width W --height H] [--threads 2]

VENV is a Python 3.11 venv with `pip install bpy==5.0.1`. SCENE is a scene in
vdbphoton's format (docs/scene.md): TOML, or JSON when the name ends in
`.json`. Paths in it are relative to the scene file. OUT is a float32 RGBA
EXR (ZIP), linear, no view transform (alpha is 1: the film is not
transparent). Command-line values override [render] spp/seed/width/height.

Everything that would bias a reference is off, as /work/shared/REFERENCE.md
lists and scripts/README.md checked: no clamping (direct and indirect 0), no
adaptive sampling, no light tree, light sampling threshold 0, no path
guiding, no denoising, box pixel filter of 1 px, volume precision FULL,
volume clipping 0, volume interpolation Linear, unbiased (null scattering)
volume integrator, Standard view transform with no look/exposure/gamma, all
bounce limits = [render] max_bounces (transparent 1024).

Mapping of the format onto Blender (conventions of docs/scene.md):
  [camera]      pinhole, sensor fit VERTICAL, angle_y = vfov; oriented from
                position/look_at/up (camera -Z forward, +Y up).
  sun           Sun light, Strength = irradiance (W/m^2), Angle = angle;
                shines along -direction. Not visible to camera rays (neither
                is vdbphoton's).
  point, spot   Point/Spot light of radius 0, no soft falloff, Power =
                4*pi*intensity (W/sr); spot Size = cone_angle, Blend = blend.
  RGB values    a light's colour = value / max(value), its power/strength the
                max component.
  [environment] radiance: World Background colour, strength 1. map: an
                Environment Texture (Blender's own equirectangular mapping,
                Closest interpolation, like vdbphoton's lookup) x strength;
                rotate_z turns the map about +Z (Mapping node, Rotation Z =
                -rotate_z, so that a direction w sees the texel at
                R(-rotate_z) w, as vdbphoton's light.rs defines it).
                Measured (64 x 32 map of texel coordinates, cameras along
                +X, +Y and up, rotate_z 0 and 90): both pick the same texel
                row and the same rotation sense, but vdbphoton's map is
                turned 180 degrees about Z against Blender's (towards +X
                Cycles shows u = 0.5, the map's centre; vdbphoton u = 0,
                its edge; towards +Y Cycles u = 0.25, vdbphoton 0.75).
                This script keeps Blender's mapping, so a scene with a map
                shows that difference.
  [[volume]]    a Volume object reading `file`; transform translate/rotate
                (XYZ Euler)/scale as the object's location/rotation/scale, or
                matrix as its world matrix (Blender applies it after the
                file's own transform, as vdbphoton does).
  Principled    a Principled Volume with the same inputs; Density Attribute =
                density_grid, Temperature Attribute = temperature_grid (empty
                without one: Cycles then uses Temperature itself, as
                vdbphoton does), Color Attribute = color_grid; a flame_grid
                multiplies Emission Strength (Attribute x Math node).
  raw keys      Attribute(density_grid) drives Volume Scatter (Density =
                max(sigma_s)*d, Color = sigma_s/max; HG Anisotropy g, one
                node per lobe of an hg_mix with its weight share), Volume
                Absorption (Density = max(sigma_a)*d, Color = 1 - sigma_a/max,
                since Cycles' sigma_a = Density*(1 - Color)) and Emission
                (Strength = max(emission)*d, Color = emission/max), added.

Keys it cannot reproduce stop the script with a message naming the key
(phase "schlick", render.integrator other than "path", render.aovs = true, a
seed beyond Cycles' 2^31 - 1). Unknown keys are errors, as in vdbphoton.

Known differences that are not errors (printed as notes): vdbphoton applies
Emission Strength only where the density is > 0, and blackbody emission
without a temperature grid too; Cycles' shader runs wherever its volume mesh
(built around the active voxels of the grids) is. vdbphoton's raw keys
ignore color_grid and flame_grid; so does this script.

Printed: RENDER_TIME, the wall time of bpy.ops.render.render (Cycles' scene
synchronisation, i.e. VDB loading and NanoVDB / volume mesh build, plus path
tracing; the bpy module prints no per-phase times), and TOTAL_WALL, the whole
script (Python start, bpy import, scene build, render, EXR write).
"""
import argparse
import json
import math
import os
import sys
import time

T_START = time.time()

try:
    import tomllib
except ImportError:  # Python < 3.11
    tomllib = None

import bpy
from mathutils import Matrix, Vector


class SceneError(Exception):
    pass


def fail(msg):
    raise SceneError(msg)


# ---------------------------------------------------------------- scene file

def load_scene(path):
    with open(path, 'rb') as f:
        data = f.read()
    if path.endswith('.json'):
        return json.loads(data.decode('utf-8'))
    if tomllib is None:
        fail('reading TOML needs Python >= 3.11 (tomllib)')
    return tomllib.loads(data.decode('utf-8'))


def check_keys(table, allowed, where):
    if not isinstance(table, dict):
        fail(f'{where} must be a table')
    for k in table:
        if k not in allowed:
            fail(f"unknown key '{k}' in {where} (expected one of: {', '.join(allowed)})")


def num(v, key):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        fail(f"key '{key}': expected a finite number, got {v!r}")
    return float(v)


def integer(v, key):
    if isinstance(v, bool) or not isinstance(v, int):
        fail(f"key '{key}': expected an integer, got {v!r}")
    return v


def vec3(v, key):
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        fail(f"key '{key}': expected [x, y, z], got {v!r}")
    return [num(x, key) for x in v]


def rgb(v, key):
    """[r, g, b] or one number meaning grey."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        x = num(v, key)
        return [x, x, x]
    return vec3(v, key)


def nonneg_rgb(v, key):
    c = rgb(v, key)
    if min(c) < 0:
        fail(f"key '{key}': must be >= 0, got {v!r}")
    return c


def split_rgb(c):
    """(colour with max component 1, that max); black gives (white, 0)."""
    m = max(c)
    if m <= 0:
        return (1.0, 1.0, 1.0), 0.0
    return tuple(x / m for x in c), m


def resolve(base, p):
    return p if os.path.isabs(p) else os.path.normpath(os.path.join(base, p))


# ------------------------------------------------------------------- set-up

def setup_render(scene, r, args, out):
    check_keys(r, ['width', 'height', 'spp', 'seed', 'max_bounces', 'integrator',
                   'output', 'preview', 'exposure', 'aovs'], '[render]')
    if r.get('integrator', 'path') != 'path':
        fail(f"key 'integrator' in [render]: only \"path\" can be rendered with Cycles, got {r['integrator']!r}")
    if r.get('aovs', False):
        fail("key 'aovs' in [render]: AOV layers are not reproduced; set it false or drop it")
    width = args.width if args.width else integer(r.get('width', 320), 'render.width')
    height = args.height if args.height else integer(r.get('height', 240), 'render.height')
    spp = args.spp if args.spp else integer(r.get('spp', 64), 'render.spp')
    seed = args.seed if args.seed is not None else integer(r.get('seed', 0), 'render.seed')
    mb = integer(r.get('max_bounces', 256), 'render.max_bounces')
    if not (0 <= seed <= 2147483647):
        fail(f"key 'seed' in [render]: Cycles' seed is 0 ..= 2147483647, got {seed}")
    if mb > 1024:
        fail(f"key 'max_bounces' in [render]: Cycles allows at most 1024, got {mb}")

    scene.render.engine = 'CYCLES'
    cy = scene.cycles
    cy.device = 'CPU'
    cy.samples = spp
    cy.seed = seed
    cy.use_animated_seed = False
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.use_light_tree = False
    cy.light_sampling_threshold = 0.0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.use_guiding = False
    cy.volume_biased = False
    cy.pixel_filter_type = 'BOX'
    cy.filter_width = 1.0
    cy.max_bounces = mb
    cy.volume_bounces = mb
    cy.diffuse_bounces = mb
    cy.glossy_bounces = mb
    cy.transmission_bounces = mb
    cy.transparent_max_bounces = 1024
    cy.min_light_bounces = 0
    cy.min_transparent_bounces = 0
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.blur_glossy = 0.0
    cy.time_limit = 0.0
    scene.render.use_motion_blur = False
    scene.render.threads_mode = 'FIXED'
    scene.render.threads = args.threads
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0
    scene.render.film_transparent = False
    scene.render.dither_intensity = 0.0
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.image_settings.color_mode = 'RGBA'
    scene.render.image_settings.exr_codec = 'ZIP'
    scene.render.filepath = out
    return dict(width=width, height=height, spp=spp, seed=seed, max_bounces=mb)


def setup_camera(scene, c):
    check_keys(c, ['position', 'look_at', 'up', 'vfov'], '[camera]')
    pos = Vector(vec3(c.get('position', [0.0, -4.5, 0.6]), 'camera.position'))
    at = Vector(vec3(c.get('look_at', [0.0, 0.0, 0.0]), 'camera.look_at'))
    up = Vector(vec3(c.get('up', [0.0, 0.0, 1.0]), 'camera.up'))
    vfov = num(c.get('vfov', 40.0), 'camera.vfov')
    if not (0 < vfov < 180):
        fail(f"key 'vfov' in [camera]: must be in (0, 180), got {vfov}")
    f = at - pos
    if f.length == 0:
        fail("key 'look_at' in [camera]: must differ from position")
    f.normalize()
    right = f.cross(up)
    if right.length < 1e-9:
        fail("key 'up' in [camera]: must not be zero or parallel to look_at - position")
    right.normalize()
    u = right.cross(f)
    cam = bpy.data.cameras.new('Cam')
    cam.type = 'PERSP'
    cam.sensor_fit = 'VERTICAL'
    cam.angle_y = math.radians(vfov)
    cam.shift_x = cam.shift_y = 0.0
    cam.clip_start = 1e-4
    cam.clip_end = 1e6
    camo = bpy.data.objects.new('Cam', cam)
    scene.collection.objects.link(camo)
    # Camera looks along its local -Z with +Y up.
    m = Matrix((
        (right.x, u.x, -f.x, pos.x),
        (right.y, u.y, -f.y, pos.y),
        (right.z, u.z, -f.z, pos.z),
        (0, 0, 0, 1)))
    camo.matrix_world = m
    scene.camera = camo


def track_minus_z(direction):
    """Rotation that points an object's local -Z along `direction`."""
    return Vector(direction).normalized().to_track_quat('-Z', 'Y')


def setup_lights(scene, lights):
    if not isinstance(lights, list):
        fail("'light' must be an array of tables ([[light]])")
    for i, L in enumerate(lights):
        where = f'[[light]] #{i + 1}'
        if not isinstance(L, dict) or 'type' not in L:
            fail(f"missing key 'type' in {where}")
        t = L['type']
        keys = {'sun': ['type', 'direction', 'irradiance', 'angle'],
                'point': ['type', 'position', 'intensity'],
                'spot': ['type', 'position', 'direction', 'intensity', 'cone_angle',
                         'blend', 'cone_falloff']}
        if t not in keys:
            fail(f"key 'type' in {where}: expected sun, point or spot, got {t!r}")
        check_keys(L, keys[t], f'{where} (type = "{t}")')
        ld = bpy.data.lights.new(f'L{i}', type=t.upper())
        lo = bpy.data.objects.new(f'L{i}', ld)
        scene.collection.objects.link(lo)
        lo.rotation_mode = 'QUATERNION'
        ld.use_temperature = False
        ld.exposure = 0.0
        if t == 'sun':
            for k in ('direction', 'irradiance'):
                if k not in L:
                    fail(f"missing key '{k}' in {where}")
            d = vec3(L['direction'], 'light.direction')
            if Vector(d).length == 0:
                fail(f"key 'direction' in {where}: must not be zero")
            col, e = split_rgb(nonneg_rgb(L['irradiance'], 'light.irradiance'))
            ld.color = col
            ld.energy = e
            angle = num(L.get('angle', 0.0), 'light.angle')
            if not (0 <= angle < 180):
                fail(f"key 'angle' in {where}: must be in [0, 180), got {angle}")
            ld.angle = math.radians(angle)
            # Blender's sun shines along its local -Z; `direction` points to the sun.
            lo.rotation_quaternion = track_minus_z([-x for x in d])
        else:
            for k in ('position', 'intensity') + (('direction',) if t == 'spot' else ()):
                if k not in L:
                    fail(f"missing key '{k}' in {where}")
            lo.location = Vector(vec3(L['position'], 'light.position'))
            col, inten = split_rgb(nonneg_rgb(L['intensity'], 'light.intensity'))
            ld.color = col
            ld.energy = 4.0 * math.pi * inten  # Blender Power P = 4 pi I, spots too
            ld.shadow_soft_size = 0.0
            ld.use_soft_falloff = False
            if t == 'spot':
                d = vec3(L['direction'], 'light.direction')
                if Vector(d).length == 0:
                    fail(f"key 'direction' in {where}: must not be zero")
                cone = num(L.get('cone_angle', 45.0), 'light.cone_angle')
                if not (0 < cone <= 180):
                    fail(f"key 'cone_angle' in {where}: must be in (0, 180], got {cone}")
                if 'blend' in L and 'cone_falloff' in L:
                    fail(f"keys 'blend' and 'cone_falloff' in {where}: give only one")
                blend = num(L.get('blend', L.get('cone_falloff', 0.15)), 'light.blend')
                if not (0 <= blend <= 1):
                    fail(f"key 'blend' in {where}: must be in [0, 1], got {blend}")
                ld.spot_size = math.radians(cone)
                ld.spot_blend = blend
                ld.show_cone = False
                lo.rotation_quaternion = track_minus_z(d)


def setup_world(scene, env, base):
    check_keys(env, ['radiance', 'map', 'strength', 'rotate_z'], '[environment]')
    world = bpy.data.worlds.new('World')
    world.use_nodes = True
    nt = world.node_tree
    bg = nt.nodes['Background']
    if 'map' in env:
        if 'radiance' in env:
            fail("key 'radiance' in [environment]: not together with 'map'")
        strength = num(env.get('strength', 1.0), 'environment.strength')
        rot = num(env.get('rotate_z', 0.0), 'environment.rotate_z')
        path = resolve(base, env['map'])
        if not os.path.exists(path):
            fail(f"key 'map' in [environment]: cannot read {path}")
        img = bpy.data.images.load(path)
        img.colorspace_settings.name = 'Non-Color'  # linear values as stored
        tex = nt.nodes.new('ShaderNodeTexEnvironment')
        tex.image = img
        tex.projection = 'EQUIRECTANGULAR'
        tex.interpolation = 'Closest'
        tc = nt.nodes.new('ShaderNodeTexCoord')
        mp = nt.nodes.new('ShaderNodeMapping')
        mp.vector_type = 'POINT'
        # vdbphoton looks up the map at the world direction rotated by -rotate_z.
        mp.inputs['Rotation'].default_value = (0.0, 0.0, -math.radians(rot))
        nt.links.new(tc.outputs['Generated'], mp.inputs['Vector'])
        nt.links.new(mp.outputs['Vector'], tex.inputs['Vector'])
        nt.links.new(tex.outputs['Color'], bg.inputs['Color'])
        bg.inputs['Strength'].default_value = strength
    else:
        for k in ('strength', 'rotate_z'):
            if k in env:
                fail(f"key '{k}' in [environment]: only with 'map'")
        c = nonneg_rgb(env.get('radiance', 0.0), 'environment.radiance')
        bg.inputs['Color'].default_value = (c[0], c[1], c[2], 1.0)
        bg.inputs['Strength'].default_value = 1.0
    scene.world = world


PRINCIPLED_KEYS = ['density', 'color', 'absorption_color', 'anisotropy', 'emission_strength',
                   'emission_color', 'blackbody_intensity', 'blackbody_tint', 'temperature']
RAW_KEYS = ['sigma_s', 'sigma_a', 'emission', 'phase']


def new_material(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    m.cycles.volume_interpolation = 'LINEAR'
    return m, nt


def attribute(nt, name):
    a = nt.nodes.new('ShaderNodeAttribute')
    a.attribute_type = 'GEOMETRY'
    a.attribute_name = name
    return a.outputs['Factor']


def times(nt, socket, k):
    """socket * k (a Math node)."""
    n = nt.nodes.new('ShaderNodeMath')
    n.operation = 'MULTIPLY'
    n.use_clamp = False
    nt.links.new(socket, n.inputs[0])
    n.inputs[1].default_value = k
    return n.outputs['Value']


def clamp0(nt, socket):
    n = nt.nodes.new('ShaderNodeMath')
    n.operation = 'MAXIMUM'
    nt.links.new(socket, n.inputs[0])
    n.inputs[1].default_value = 0.0
    return n.outputs['Value']


def principled_material(nt, mat, v, where, notes):
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    d = num(mat.get('density', 1.0), 'material.density')
    col = nonneg_rgb(mat.get('color', 0.5), 'material.color')
    ac = nonneg_rgb(mat.get('absorption_color', 0.0), 'material.absorption_color')
    g = num(mat.get('anisotropy', 0.0), 'material.anisotropy')
    es = num(mat.get('emission_strength', 0.0), 'material.emission_strength')
    ec = nonneg_rgb(mat.get('emission_color', 1.0), 'material.emission_color')
    bi = num(mat.get('blackbody_intensity', 0.0), 'material.blackbody_intensity')
    bt = nonneg_rgb(mat.get('blackbody_tint', 1.0), 'material.blackbody_tint')
    temp = num(mat.get('temperature', 1000.0), 'material.temperature')
    for k, x in (('density', d), ('emission_strength', es), ('blackbody_intensity', bi),
                 ('temperature', temp)):
        if x < 0:
            fail(f"key '{k}' in {where}.material: must be >= 0, got {x}")
    if not (-1 <= g <= 1):
        fail(f"key 'anisotropy' in {where}.material: must be in [-1, 1], got {g}")
    pv.inputs['Density'].default_value = d
    pv.inputs['Density Attribute'].default_value = v.get('density_grid', 'density')
    pv.inputs['Color'].default_value = (*col, 1.0)
    pv.inputs['Color Attribute'].default_value = v.get('color_grid', '') or ''
    pv.inputs['Absorption Color'].default_value = (*ac, 1.0)
    pv.inputs['Anisotropy'].default_value = g
    pv.inputs['Emission Color'].default_value = (*ec, 1.0)
    pv.inputs['Blackbody Intensity'].default_value = bi
    pv.inputs['Blackbody Tint'].default_value = (*bt, 1.0)
    pv.inputs['Temperature'].default_value = temp
    # Empty name: the attribute is not found and Cycles uses Temperature as is
    # (vdbphoton without a temperature_grid does the same).
    pv.inputs['Temperature Attribute'].default_value = v.get('temperature_grid', '') or ''
    if 'flame_grid' in v and es > 0:
        nt.links.new(times(nt, clamp0(nt, attribute(nt, v['flame_grid'])), es),
                     pv.inputs['Emission Strength'])
    else:
        pv.inputs['Emission Strength'].default_value = es
    if es > 0 and max(ec) > 0:
        notes.append(f'{where}: Emission Strength > 0: vdbphoton emits it only where the density '
                     'is > 0, Cycles wherever its volume mesh is')
    if bi > 0 and 'temperature_grid' not in v:
        notes.append(f'{where}: blackbody without temperature_grid: vdbphoton emits it only '
                     'where the density is > 0, Cycles wherever its volume mesh is')
    return pv.outputs['Volume']


def add_shaders(nt, shaders):
    out = shaders[0]
    for s in shaders[1:]:
        a = nt.nodes.new('ShaderNodeAddShader')
        nt.links.new(out, a.inputs[0])
        nt.links.new(s, a.inputs[1])
        out = a.outputs['Shader']
    return out


def raw_material(nt, mat, v, where, notes):
    ss = nonneg_rgb(mat.get('sigma_s', 0.0), 'material.sigma_s')
    sa = nonneg_rgb(mat.get('sigma_a', 0.0), 'material.sigma_a')
    em = nonneg_rgb(mat.get('emission', 0.0), 'material.emission')
    ph = mat.get('phase', {'type': 'isotropic'})
    if not isinstance(ph, dict) or 'type' not in ph:
        fail(f"key 'phase' in {where}.material: expected a table with a 'type'")
    pt = ph['type']
    if pt == 'isotropic':
        check_keys(ph, ['type'], f'{where}.material.phase (isotropic)')
        lobes = [(0.0, 1.0)]
    elif pt == 'hg':
        check_keys(ph, ['type', 'g'], f'{where}.material.phase (hg)')
        if 'g' not in ph:
            fail(f"missing key 'g' in {where}.material.phase")
        lobes = [(num(ph['g'], 'material.phase.g'), 1.0)]
    elif pt == 'hg_mix':
        check_keys(ph, ['type', 'lobes'], f'{where}.material.phase (hg_mix)')
        ls = ph.get('lobes')
        if not isinstance(ls, list) or not ls:
            fail(f"key 'phase.lobes' in {where}.material: expected a non-empty array")
        lobes = []
        for j, lb in enumerate(ls):
            check_keys(lb, ['g', 'weight'], f'{where}.material.phase.lobes[{j}]')
            lobes.append((num(lb['g'], f'material.phase.lobes[{j}].g'),
                          num(lb['weight'], f'material.phase.lobes[{j}].weight')))
        if min(w for _, w in lobes) < 0 or sum(w for _, w in lobes) <= 0:
            fail(f"key 'phase.lobes' in {where}.material: weights must be >= 0 with a positive sum")
        tot = sum(w for _, w in lobes)
        lobes = [(g, w / tot) for g, w in lobes if w > 0]
    elif pt == 'schlick':
        fail(f"key 'phase.type' in {where}.material: Cycles has no Schlick phase function "
             "(use \"hg\" with the same g)")
    else:
        fail(f"key 'phase.type' in {where}.material: unknown phase {pt!r}")
    for g, _ in lobes:
        if not (-1 <= g <= 1):
            fail(f"key 'phase.g' in {where}.material: must be in [-1, 1], got {g}")
    for k in ('color_grid', 'flame_grid', 'temperature_grid'):
        if k in v:
            notes.append(f'{where}: {k} is ignored with raw coefficients (by vdbphoton too)')
    dens = clamp0(nt, attribute(nt, v.get('density_grid', 'density')))
    shaders = []
    col, m = split_rgb(ss)
    if m > 0:
        for g, w in lobes:
            n = nt.nodes.new('ShaderNodeVolumeScatter')
            n.phase = 'HENYEY_GREENSTEIN'
            n.inputs['Color'].default_value = (*col, 1.0)
            n.inputs['Anisotropy'].default_value = g
            nt.links.new(times(nt, dens, m * w), n.inputs['Density'])
            shaders.append(n.outputs['Volume'])
    col, m = split_rgb(sa)
    if m > 0:
        n = nt.nodes.new('ShaderNodeVolumeAbsorption')
        n.inputs['Color'].default_value = (1 - col[0], 1 - col[1], 1 - col[2], 1.0)
        nt.links.new(times(nt, dens, m), n.inputs['Density'])
        shaders.append(n.outputs['Volume'])
    col, m = split_rgb(em)
    if m > 0:
        n = nt.nodes.new('ShaderNodeEmission')
        n.inputs['Color'].default_value = (*col, 1.0)
        nt.links.new(times(nt, dens, m), n.inputs['Strength'])
        shaders.append(n.outputs['Emission'])
    if not shaders:
        return None
    return add_shaders(nt, shaders)


def setup_volume(scene, i, v, base, notes):
    where = f'[[volume]] #{i + 1}'
    check_keys(v, ['file', 'density_grid', 'temperature_grid', 'flame_grid', 'color_grid',
                   'transform', 'material'], where)
    if 'file' not in v:
        fail(f"missing key 'file' in {where}")
    path = resolve(base, v['file'])
    if not os.path.exists(path):
        fail(f"key 'file' in {where}: cannot read {path}")
    vol = bpy.data.volumes.new(f'vol{i}')
    vol.filepath = path
    vol.render.precision = 'FULL'
    vol.render.clipping = 0.0
    vo = bpy.data.objects.new(f'vol{i}', vol)
    scene.collection.objects.link(vo)
    vol.grids.load()
    names = [g.name for g in vol.grids]
    if not names:
        fail(f"key 'file' in {where}: Blender read no grids from {path}")
    for k in ('density_grid', 'temperature_grid', 'flame_grid', 'color_grid'):
        name = v.get(k, 'density' if k == 'density_grid' else None)
        if name is not None and name not in names:
            fail(f"key '{k}' in {where}: no grid '{name}' in {path} (grids: {', '.join(names)})")

    tr = v.get('transform', {})
    check_keys(tr, ['translate', 'rotate', 'scale', 'matrix'], f'{where}.transform')
    if 'matrix' in tr:
        if len(tr) > 1:
            fail(f"key 'matrix' in {where}.transform: not together with translate/rotate/scale")
        rows = tr['matrix']
        if not isinstance(rows, list) or len(rows) != 4 or any(
                not isinstance(r, list) or len(r) != 4 for r in rows):
            fail(f"key 'matrix' in {where}.transform: expected 4 rows of 4 numbers")
        m = [[num(x, 'transform.matrix') for x in r] for r in rows]
        if m[3] != [0.0, 0.0, 0.0, 1.0]:
            fail(f"key 'matrix' in {where}.transform: the last row must be 0 0 0 1")
        M = Matrix(m)
        if abs(M.determinant()) < 1e-300:
            fail(f"key 'matrix' in {where}.transform: not invertible")
        vo.matrix_world = M
    else:
        vo.location = vec3(tr.get('translate', [0, 0, 0]), 'transform.translate')
        vo.rotation_mode = 'XYZ'
        vo.rotation_euler = [math.radians(a) for a in vec3(tr.get('rotate', [0, 0, 0]),
                                                             'transform.rotate')]
        s = rgb(tr.get('scale', 1.0), 'transform.scale')
        if 0.0 in s:
            fail(f"key 'scale' in {where}.transform: no zero component")
        vo.scale = s

    mat = v.get('material', {})
    check_keys(mat, PRINCIPLED_KEYS + RAW_KEYS, f'{where}.material')
    pk = [k for k in mat if k in PRINCIPLED_KEYS]
    rk = [k for k in mat if k in RAW_KEYS]
    if pk and rk:
        fail(f"key '{rk[0]}' in {where}.material: raw keys cannot be mixed with Principled "
             f"keys ('{pk[0]}')")
    m, nt = new_material(f'vol{i}')
    shader = (raw_material if rk else principled_material)(nt, mat, v, where, notes)
    if shader is not None:
        o = nt.nodes.new('ShaderNodeOutputMaterial')
        o.target = 'CYCLES'
        nt.links.new(shader, o.inputs['Volume'])
    vo.data.materials.append(m)
    return path, names


# --------------------------------------------------------------------- main

def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('out')
    ap.add_argument('--spp', type=int)
    ap.add_argument('--seed', type=int)
    ap.add_argument('--width', type=int)
    ap.add_argument('--height', type=int)
    ap.add_argument('--threads', type=int, default=2)
    args = ap.parse_args(argv)
    scene_path = os.path.abspath(args.scene)
    out = os.path.abspath(args.out)
    base = os.path.dirname(scene_path)
    name = os.path.basename(scene_path)
    try:
        desc = load_scene(scene_path)
    except (OSError, ValueError) as e:
        print(f'{name}: {e}', file=sys.stderr)
        return 2

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    notes = []
    try:
        check_keys(desc, ['render', 'camera', 'light', 'environment', 'volume'], 'the scene')
        info = setup_render(scene, desc.get('render', {}), args, out)
        setup_camera(scene, desc.get('camera', {}))
        setup_lights(scene, desc.get('light', []))
        setup_world(scene, desc.get('environment', {}), base)
        vols = desc.get('volume', [])
        if not isinstance(vols, list) or not vols:
            fail('no [[volume]]: a scene needs at least one volume')
        for i, v in enumerate(vols):
            path, grids = setup_volume(scene, i, v, base, notes)
            print(f'volume {i + 1}: {path} grids {grids}')
    except SceneError as e:
        print(f'{name}: {e}', file=sys.stderr)
        return 2
    for n in notes:
        print('note:', n)

    print(f"SAMPLES {info['spp']} SEED {info['seed']} SIZE {info['width']}x{info['height']} "
          f"MAX_BOUNCES {info['max_bounces']} THREADS {scene.render.threads}", flush=True)
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    t1 = time.time()
    print(f'RENDER_TIME {t1 - t0:.2f} s -> {out}')
    print(f'TOTAL_WALL {time.time() - T_START:.2f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
