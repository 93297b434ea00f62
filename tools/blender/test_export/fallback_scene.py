"""Build the .blend files of tests/blender_export.rs
(`blender_exports_every_volume_whatever_its_material`) from scratch (bpy
5.0.1): Volume objects reading one cloud whose materials vdbphoton can
take, approximate or not render, a Volume object without a material, and
Attribute nodes naming a grid the file does not have.

Usage:
    VENV/bin/python tools/blender/test_export/fallback_scene.py DIR CLOUD.vdb

Writes into DIR:
  fallback.blend  the objects below side by side, and fallback.json (each
                  object's location, by which the test finds its [[volume]])
  nomat.blend     'No material' alone, filling the frame
  missing.blend   'Missing colour' alone, filling the frame

The objects:
  Good            Principled Volume, Density 4 (Density Attribute 'density')
  Ramp            Principled Volume, Density Attribute empty, Density <-
                  Math (Multiply 4) <- Color Ramp <- Attribute 'density':
                  the Color Ramp is unsupported (not the Math below it)
  Emission        an Emission shader into the Volume output (unsupported:
                  not rendered)
  No material     no material: Cycles' default volume shader
  Missing colour  Principled Volume, Density 4, Color <- Attribute 'missing'
                  (Color): black in Cycles (a missing attribute reads 0)
  Missing density Principled Volume, Density Attribute empty, Density <-
                  Attribute 'smoke' (Fac), Emission Strength 2: nothing
                  renders in Cycles
"""
import json
import math
import os
import sys

import bpy
from mathutils import Euler


def link(sc, name, data):
    o = bpy.data.objects.new(name, data)
    sc.collection.objects.link(o)
    return o


def base_scene(cam_at, resolution):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    r = sc.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y = resolution
    r.resolution_percentage = 100
    r.filepath = '//render/fallback_####'
    sc.frame_start = sc.frame_end = sc.frame_current = 1
    sc.cycles.samples = 4
    sc.view_settings.view_transform = 'Standard'
    cam = bpy.data.cameras.new('Cam')
    co = link(sc, 'Cam', cam)
    co.location = cam_at
    co.rotation_euler = Euler((math.radians(90.0), 0.0, 0.0), 'XYZ')
    sc.camera = co
    sun = bpy.data.lights.new('Sun', 'SUN')
    sun.energy = 4.0
    link(sc, 'Sun', sun).rotation_euler = Euler((math.radians(50.0), 0.0, math.radians(20.0)),
                                                'XYZ')
    w = bpy.data.worlds.new('Dim sky')
    w.use_nodes = True
    w.node_tree.nodes['Background'].inputs['Color'].default_value = (0.1, 0.12, 0.16, 1.0)
    sc.world = w
    return sc


def new_material(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    return m, nt, nt.nodes.new('ShaderNodeOutputMaterial')


def principled(name, density=4.0, density_attribute='density'):
    m, nt, out = new_material(name)
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    pv.name = 'Principled Volume'
    pv.inputs['Density'].default_value = density
    pv.inputs['Density Attribute'].default_value = density_attribute
    nt.links.new(pv.outputs['Volume'], out.inputs['Volume'])
    return m, nt, pv


def attribute(nt, name, node_name='Attribute'):
    a = nt.nodes.new('ShaderNodeAttribute')
    a.name = node_name
    a.attribute_name = name
    return a


def ramp():
    m, nt, pv = principled('Ramp material', density_attribute='')
    a = attribute(nt, 'density')
    cr = nt.nodes.new('ShaderNodeValToRGB')
    cr.name = 'Color Ramp'
    mul = nt.nodes.new('ShaderNodeMath')
    mul.name = 'Math'
    mul.operation = 'MULTIPLY'
    mul.inputs[1].default_value = 4.0
    nt.links.new(a.outputs['Fac'], cr.inputs['Fac'])
    nt.links.new(cr.outputs['Color'], mul.inputs[0])
    nt.links.new(mul.outputs['Value'], pv.inputs['Density'])
    return m


def emission():
    m, nt, out = new_material('Emission material')
    e = nt.nodes.new('ShaderNodeEmission')
    e.name = 'Emission'
    nt.links.new(e.outputs['Emission'], out.inputs['Volume'])
    return m


def missing_colour():
    m, nt, pv = principled('Missing colour material')
    a = attribute(nt, 'missing', 'Colour attribute')
    nt.links.new(a.outputs['Color'], pv.inputs['Color'])
    return m


def missing_density():
    m, nt, pv = principled('Missing density material', density_attribute='')
    a = attribute(nt, 'smoke', 'Smoke attribute')
    nt.links.new(a.outputs['Fac'], pv.inputs['Density'])
    pv.inputs['Emission Strength'].default_value = 2.0
    return m


def add_volume(sc, name, cloud, mat, at):
    vol = bpy.data.volumes.new(name)
    vol.filepath = cloud
    o = link(sc, name, vol)
    o.location = at
    if mat is not None:
        vol.materials.append(mat)
    return o


def main():
    a = sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:]
    out, cloud = os.path.abspath(a[0]), os.path.abspath(a[1])
    sc = base_scene((0.0, -9.0, 0.0), (96, 48))
    layout = {}
    for i, (name, make) in enumerate([('Good', lambda: principled('Good material')[0]),
                                      ('Ramp', ramp), ('Emission', emission),
                                      ('No material', lambda: None),
                                      ('Missing colour', missing_colour),
                                      ('Missing density', missing_density)]):
        o = add_volume(sc, name, cloud, make(), (-3.0 + 1.4 * (i % 5), 0.0, 0.7 - 1.4 * (i // 5)))
        layout[name] = list(o.location)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'fallback.blend'))
    with open(os.path.join(out, 'fallback.json'), 'w') as f:
        json.dump(layout, f)
    for blend, name, make in (('nomat.blend', 'No material', lambda: None),
                              ('missing.blend', 'Missing colour', missing_colour)):
        sc = base_scene((0.08, -2.3, 0.21), (48, 40))
        add_volume(sc, name, cloud, make(), (0.0, 0.0, 0.0))
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, blend))
    print('built', out)


if __name__ == '__main__':
    main()
    sys.stdout.flush()
    os._exit(0)
