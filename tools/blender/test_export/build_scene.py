"""Build the .blend files of tests/blender_export.rs from scratch (bpy 5.0.1).

Usage:
    VENV/bin/python tools/blender/test_export/build_scene.py OUTDIR \
        --cloud CLOUD_0025.vdb --cache CACHEDIR --bad-cache BADCACHEDIR

Writes into OUTDIR:
  main.blend   what the exporter must reproduce: a camera (rotated and
               rolled, 42 mm lens on a 32 x 18 mm sensor, horizontal fit,
               shift), a sun and a point light, a dim constant world, a
               Volume object reading the image sequence CLOUD_####.vdb
               (Start Frame 4, Offset 1: scene frame 25 shows file 23, the
               one that exists) with a Principled Volume and a rotated,
               non-uniformly scaled transform, and a Mantaflow smoke + fire
               domain (2.5 x 2.5 x 4.5, resolution 64, rotated 30 degrees
               about Z, Flame Ignition 1.5, Maximum Temperature 3.0 as in
               blender_smoke/make_smoke_info.json, cache Offset 2: frame 25
               reads CACHEDIR/data/fluid_data_0023.vdb) with Blender's Quick
               Smoke fire material (Principled Volume, Density 5, Blackbody
               Intensity 1, the rest default) and its Fire + Smoke flow
               (a small sphere, invisible to every ray type, so that Blender
               gives the domain fire and loads its flame grid).
               Render 192 x 144 at 50 %, frames 24-26, output
               //render/smoke_####.
  bad.blend    things the exporter cannot reproduce and must warn about:
               an area light, a soft point light, a Sky Texture world, a
               metaball and a mesh with volume materials, a plain mesh, and
               two smoke domains whose cache (BADCACHEDIR, a file with only
               a 'density' grid) has no flame grid: 'Fire Domain' with a
               (visible) Fire flow, whose fire material's temperature Blender
               makes from the missing flame grid, and 'Smoke Domain' whose
               Flow collection holds no flow (no fire: Blender's temperature
               is 0); plus one Volume object so that there is something to
               export.
  nocam.blend  a Volume object and no camera.

Domain settings are set before the cache directory: changing a domain
setting afterwards makes Blender delete the cache.
"""
import math
import os
import sys

import bpy
import bmesh  # noqa: E402  (after bpy)
from mathutils import Euler, Vector


def args():
    a = sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:]
    out = a[0]
    opts = dict(zip(a[1::2], a[2::2]))
    return out, opts['--cloud'], opts['--cache'], opts['--bad-cache']


def new_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def cube_mesh(name, size=2.0):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size)
    bm.to_mesh(me)
    bm.free()
    return me


def link(sc, name, data):
    o = bpy.data.objects.new(name, data)
    sc.collection.objects.link(o)
    return o


def principled(name, **inputs):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    pv.name = 'Principled Volume'
    for k, v in inputs.items():
        pv.inputs[k].default_value = v
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(pv.outputs['Volume'], out.inputs['Volume'])
    return m


def camera(sc):
    cam = bpy.data.cameras.new('Cam')
    cam.lens = 42.0
    cam.sensor_width = 32.0
    cam.sensor_height = 18.0
    cam.sensor_fit = 'HORIZONTAL'
    cam.shift_x = 0.03
    cam.shift_y = -0.02
    co = link(sc, 'Cam', cam)
    co.location = (-0.1, -5.0, 0.75)
    co.rotation_mode = 'XYZ'
    co.rotation_euler = Euler((math.radians(88.0), math.radians(3.0), math.radians(4.0)), 'XYZ')
    sc.camera = co
    return co


def render_settings(sc):
    r = sc.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = 192, 144, 50
    r.filepath = '//render/smoke_####'
    sc.frame_start, sc.frame_end, sc.frame_current = 24, 26, 25
    cy = sc.cycles
    cy.samples = 64
    cy.seed = 7
    cy.volume_bounces = 3
    cy.max_bounces = 8
    sc.view_settings.view_transform = 'Standard'


def world_colour(sc, colour):
    w = bpy.data.worlds.new('Dim sky')
    w.use_nodes = True
    bg = w.node_tree.nodes['Background']
    bg.inputs['Color'].default_value = (*colour, 1.0)
    bg.inputs['Strength'].default_value = 1.0
    sc.world = w


def cloud_object(sc, cloud, name='Cloud'):
    vol = bpy.data.volumes.new(name)
    vol.filepath = cloud
    vol.is_sequence = True
    vol.frame_start = 4
    vol.frame_duration = 40
    vol.frame_offset = 1
    vol.sequence_mode = 'CLIP'
    o = link(sc, name, vol)
    o.location = (0.9, 0.4, 0.85)
    o.rotation_mode = 'XYZ'
    o.rotation_euler = Euler((math.radians(20.0), math.radians(-15.0), math.radians(35.0)), 'XYZ')
    o.scale = (0.9, 0.7, 0.8)
    vol.materials.append(principled(
        'Cloud material', **{'Density': 6.0, 'Color': (0.9, 0.75, 0.6, 1.0),
                             'Absorption Color': (0.1, 0.2, 0.3, 1.0), 'Anisotropy': 0.4}))
    return o


def domain(sc, cache, material, name='Smoke Domain', location=(-1.1, 0.8, 1.0),
           rot_z=30.0, offset=0, flow_group=None):
    o = link(sc, name, cube_mesh(name))
    o.location = location
    o.rotation_euler = (0.0, 0.0, math.radians(rot_z))
    o.scale = (1.25, 1.25, 2.25)
    m = o.modifiers.new('Fluid', 'FLUID')
    m.fluid_type = 'DOMAIN'
    ds = m.domain_settings
    ds.domain_type = 'GAS'
    ds.resolution_max = 64
    ds.use_adaptive_domain = False
    ds.cache_type = 'ALL'
    ds.cache_data_format = 'OPENVDB'
    ds.cache_frame_start = 1
    ds.cache_frame_end = 40
    ds.cache_frame_offset = offset
    ds.flame_ignition = 1.5
    ds.flame_max_temp = 3.0
    if flow_group is not None:
        ds.fluid_group = flow_group
    o.data.materials.append(material)
    ds.cache_directory = cache  # last: changing settings afterwards deletes the cache
    return o


def quick_smoke_fire(name='Smoke Domain Material'):
    """Blender's Quick Smoke material with fire (object_quick_effects.py):
    a Principled Volume with Density 5 and Blackbody Intensity 1, the rest
    default (Color 0.5, Temperature 1000 K x attribute 'temperature')."""
    return principled(name, **{'Density': 5.0, 'Blackbody Intensity': 1.0})


def fire_flow(sc, name, location, radius=0.2, visible=False, segments=(16, 8)):
    """A Fire + Smoke flow: Blender gives a domain fire (allocates and loads
    its flame grid) only when such a flow takes part. Invisible to every
    ray type unless `visible`, so Cycles renders nothing of it. A UV sphere
    of `segments` (u, v)."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments[0], v_segments=segments[1], radius=radius)
    bm.to_mesh(me)
    bm.free()
    o = link(sc, name, me)
    o.location = location
    m = o.modifiers.new('Fluid', 'FLUID')
    m.fluid_type = 'FLOW'
    m.flow_settings.flow_type = 'BOTH'
    m.flow_settings.flow_behavior = 'INFLOW'
    if not visible:
        for k in ('visible_camera', 'visible_diffuse', 'visible_glossy', 'visible_transmission',
                  'visible_volume_scatter', 'visible_shadow'):
            setattr(o, k, False)
    return o


def main():
    out, cloud, cache, bad_cache = (os.path.abspath(p) for p in args())
    os.makedirs(out, exist_ok=True)

    # ---------------------------------------------------------------- main
    sc = new_scene()
    render_settings(sc)
    camera(sc)
    sun = bpy.data.lights.new('Sun', 'SUN')
    sun.energy = 5.0
    sun.color = (1.0, 0.95, 0.88)
    sun.angle = math.radians(0.5)
    so = link(sc, 'Sun', sun)
    so.rotation_euler = Euler((math.radians(40.0), math.radians(25.0), math.radians(-30.0)), 'XYZ')
    pt = bpy.data.lights.new('Lamp', 'POINT')
    pt.energy = 150.0
    pt.color = (0.6, 0.8, 1.0)
    pt.shadow_soft_size = 0.0
    po = link(sc, 'Lamp', pt)
    po.location = (-0.5, -2.5, 3.0)
    world_colour(sc, (0.05, 0.06, 0.08))
    cloud_object(sc, cloud)
    fire_flow(sc, 'Emitter', (-1.1, 0.8, -0.6))
    domain(sc, cache, quick_smoke_fire(), offset=2)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'main.blend'))

    # ----------------------------------------------------------------- bad
    sc = new_scene()
    render_settings(sc)
    camera(sc)
    area = bpy.data.lights.new('Softbox', 'AREA')
    area.energy = 100.0
    link(sc, 'Softbox', area).location = (0, -3, 3)
    soft = bpy.data.lights.new('Bulb', 'POINT')
    soft.energy = 50.0
    soft.shadow_soft_size = 0.25
    link(sc, 'Bulb', soft).location = (2, -2, 2)
    w = bpy.data.worlds.new('Sky world')
    w.use_nodes = True
    sky = w.node_tree.nodes.new('ShaderNodeTexSky')
    sky.name = 'Sky Texture'
    w.node_tree.links.new(sky.outputs['Color'], w.node_tree.nodes['Background'].inputs['Color'])
    sc.world = w
    mb = bpy.data.metaballs.new('Blob')
    mb.elements.new()
    mbo = link(sc, 'Blob', mb)
    mb.materials.append(principled('Blob fog', Density=2.0))
    fog = link(sc, 'Fog box', cube_mesh('Fog box'))
    fog.data.materials.append(principled('Fog material', Density=0.5))
    link(sc, 'Ground', cube_mesh('Ground', 1.0)).location = (0, 0, -3)
    cloud_object(sc, cloud)
    fire_flow(sc, 'Torch', (0.0, 0.0, -0.5), visible=True)
    domain(sc, bad_cache, principled('Fire material', **{
        'Density': 5.0, 'Blackbody Intensity': 1.0, 'Temperature Attribute': 'temperature'}),
        name='Fire Domain')
    no_flows = bpy.data.collections.new('No flows')
    no_flows.use_fake_user = True  # kept in the file although empty and unlinked
    domain(sc, bad_cache, principled('Smoke material', **{
        'Density': 5.0, 'Blackbody Intensity': 1.0, 'Temperature Attribute': 'temperature'}),
        name='Smoke Domain', location=(1.5, 0.8, 1.0), flow_group=no_flows)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'bad.blend'))

    # --------------------------------------------------------------- nocam
    sc = new_scene()
    render_settings(sc)
    cloud_object(sc, cloud)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'nocam.blend'))
    print('built', out)


if __name__ == '__main__':
    main()
    sys.stdout.flush()
    os._exit(0)
