"""Build phases.blend for tests/blender_export.rs
(`blender_exports_every_volume_scatter_phase`) from scratch (bpy 5.0.1):
Volume objects reading one cloud, each with a Volume Scatter material of
one of Blender 5's phases, or a case the exporter must clamp, mix or
refuse.

Usage:
    VENV/bin/python tools/blender/test_export/phase_scene.py OUT.blend CLOUD.vdb

Writes OUT.blend and, beside it, phases.json: each object's name and
location, by which the test finds its [[volume]].

The cases (the density of every Scatter node is the cloud's 'density'
grid through one Attribute node):
  HG                    Henyey-Greenstein, Anisotropy 0.6
  Fournier-Forand       Backscatter 0.2, IOR 1.15
  Draine                Anisotropy -0.3, Alpha 2.5
  Rayleigh              (Anisotropy 0.7 set before the phase: hidden, unused)
  Mie                   Diameter 8.5
  Mie by a Value node   Diameter from a Value node, 12.5
  Clamped FF            Backscatter 0.7, IOR 2.5 (outside Blender's ranges:
                        a script can set them)
  Clamped Draine        Anisotropy -1.4, Alpha 900
  Clamped Mie           Diameter from a Value node, 80
  Mixed                 Mie (Diameter 20, Color 0.3) + Rayleigh (Color 0.9) +
                        Volume Absorption
  Two Mie               two Mie nodes of Diameter 20
  HG mix                HG 0.8 (Color 0.6) + HG -0.3 (Color 0.2)
  Noisy Mie             Mie whose Diameter a Noise Texture drives
  Principled            Principled Volume, Anisotropy 1.7 (set by script)
"""
import json
import math
import os
import sys

import bpy
from mathutils import Euler


def args():
    a = sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:]
    return os.path.abspath(a[0]), os.path.abspath(a[1])


def link(sc, name, data):
    o = bpy.data.objects.new(name, data)
    sc.collection.objects.link(o)
    return o


def grey(v):
    return (v, v, v, 1.0)


def material(name, scatters, absorb=False):
    """Volume Scatter nodes (phase, {socket: value or ('value', v) or
    'noise'}, colour) added together, their Density the 'density'
    attribute."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    attr = nt.nodes.new('ShaderNodeAttribute')
    attr.attribute_name = 'density'
    shaders = []
    for i, (phase, inputs, colour, node_name) in enumerate(scatters):
        vs = nt.nodes.new('ShaderNodeVolumeScatter')
        vs.name = node_name
        if phase == 'RAYLEIGH':
            # A value the Rayleigh phase hides: it must not be read.
            vs.inputs['Anisotropy'].default_value = 0.7
        vs.phase = phase
        vs.inputs['Color'].default_value = grey(colour)
        nt.links.new(attr.outputs['Fac'], vs.inputs['Density'])
        for sock, v in inputs.items():
            if v == 'noise':
                tex = nt.nodes.new('ShaderNodeTexNoise')
                tex.name = 'Noise Texture'
                nt.links.new(tex.outputs['Fac'], vs.inputs[sock])
            elif isinstance(v, tuple):
                val = nt.nodes.new('ShaderNodeValue')
                val.name = f'Value {i}'
                val.outputs[0].default_value = v[1]
                nt.links.new(val.outputs[0], vs.inputs[sock])
            else:
                vs.inputs[sock].default_value = v
        shaders.append(vs.outputs['Volume'])
    if absorb:
        va = nt.nodes.new('ShaderNodeVolumeAbsorption')
        va.inputs['Color'].default_value = grey(0.5)
        nt.links.new(attr.outputs['Fac'], va.inputs['Density'])
        shaders.append(va.outputs['Volume'])
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    top = shaders[0]
    for s in shaders[1:]:
        add = nt.nodes.new('ShaderNodeAddShader')
        nt.links.new(top, add.inputs[0])
        nt.links.new(s, add.inputs[1])
        top = add.outputs['Shader']
    nt.links.new(top, out.inputs['Volume'])
    return m


def principled(name, anisotropy):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    pv.name = 'Principled Volume'
    pv.inputs['Anisotropy'].default_value = anisotropy
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(pv.outputs['Volume'], out.inputs['Volume'])
    return m


CASES = [
    ('HG', [('HENYEY_GREENSTEIN', {'Anisotropy': 0.6}, 0.8, 'Volume Scatter')]),
    ('Fournier-Forand', [('FOURNIER_FORAND', {'Backscatter': 0.2, 'IOR': 1.15}, 0.8,
                          'Volume Scatter')]),
    ('Draine', [('DRAINE', {'Anisotropy': -0.3, 'Alpha': 2.5}, 0.8, 'Volume Scatter')]),
    ('Rayleigh', [('RAYLEIGH', {}, 0.8, 'Volume Scatter')]),
    ('Mie', [('MIE', {'Diameter': 8.5}, 0.8, 'Volume Scatter')]),
    ('Mie by a Value node', [('MIE', {'Diameter': ('value', 12.5)}, 0.8, 'Volume Scatter')]),
    ('Clamped FF', [('FOURNIER_FORAND', {'Backscatter': 0.7, 'IOR': 2.5}, 0.8,
                     'Volume Scatter')]),
    ('Clamped Draine', [('DRAINE', {'Anisotropy': -1.4, 'Alpha': 900.0}, 0.8,
                         'Volume Scatter')]),
    ('Clamped Mie', [('MIE', {'Diameter': ('value', 80.0)}, 0.8, 'Volume Scatter')]),
    ('Mixed', [('MIE', {'Diameter': 20.0}, 0.3, 'Mie scatter'),
               ('RAYLEIGH', {}, 0.9, 'Rayleigh scatter')]),
    ('Two Mie', [('MIE', {'Diameter': 20.0}, 0.5, 'Mie A'),
                 ('MIE', {'Diameter': 20.0}, 0.4, 'Mie B')]),
    ('HG mix', [('HENYEY_GREENSTEIN', {'Anisotropy': 0.8}, 0.6, 'Forward'),
                ('HENYEY_GREENSTEIN', {'Anisotropy': -0.3}, 0.2, 'Backward')]),
    ('Noisy Mie', [('MIE', {'Diameter': 'noise'}, 0.8, 'Volume Scatter')]),
]


def main():
    out, cloud = args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    r = sc.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = 80, 48, 100
    r.filepath = '//render/phases_####'
    sc.frame_start = sc.frame_end = sc.frame_current = 1
    sc.cycles.samples = 4
    sc.view_settings.view_transform = 'Standard'
    cam = bpy.data.cameras.new('Cam')
    co = link(sc, 'Cam', cam)
    co.location = (0.0, -16.0, 0.0)
    co.rotation_euler = Euler((math.radians(90.0), 0.0, 0.0), 'XYZ')
    sc.camera = co
    sun = bpy.data.lights.new('Sun', 'SUN')
    sun.energy = 3.0
    link(sc, 'Sun', sun).rotation_euler = Euler((math.radians(50.0), 0.0, math.radians(20.0)),
                                                'XYZ')
    w = bpy.data.worlds.new('Dim sky')
    w.use_nodes = True
    w.node_tree.nodes['Background'].inputs['Color'].default_value = (0.05, 0.06, 0.08, 1.0)
    sc.world = w

    cases = [(name, material(f'{name} material', scatters, absorb=(name == 'Mixed')))
             for name, scatters in CASES]
    cases.append(('Principled', principled('Principled material', 1.7)))
    layout = {}
    for i, (name, mat) in enumerate(cases):
        vol = bpy.data.volumes.new(name)
        vol.filepath = cloud
        o = link(sc, name, vol)
        o.location = (-3.9 + 1.3 * (i % 7), 0.0, 1.3 - 1.3 * (i // 7))
        vol.materials.append(mat)
        layout[name] = list(o.location)
    bpy.ops.wm.save_as_mainfile(filepath=out)
    with open(os.path.join(os.path.dirname(out), 'phases.json'), 'w') as f:
        json.dump(layout, f)
    print('built', out)


if __name__ == '__main__':
    main()
    sys.stdout.flush()
    os._exit(0)
