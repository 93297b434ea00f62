"""Build the .blend files of tests/blender_export.rs's mesh test from scratch
(bpy 5.0.1), and what the exporter must write for them.

Usage:
    VENV/bin/python tools/blender/test_export/mesh_scene.py OUTDIR --cloud CLOUD.vdb

Writes into OUTDIR:
  meshes.blend   a camera, a sun, a dim world, a Volume object (CLOUD.vdb),
                 Film > Transparent, frames 1-3, and meshes of every kind the
                 exporter must handle:
                   Ground        a plane (2 triangles), shadow catcher
                   Ball          a UV sphere (960 triangles), holdout
                   Ball copy     a linked duplicate of Ball (the same mesh
                                 data: the same file), Ray Visibility >
                                 Shadow off
                   Props A       an empty instancing collection 'Props' (not
                                 in the view layer; instance offset
                                 (0.1, 0.2, 0)), which holds 'Prop Ball' (a
                                 UV sphere of 528 triangles, Glossy off,
                                 shadow catcher)
                   Scatter       three points, Geometry Nodes Instance on
                                 Points of 'Prop Ball' (Object Info, As
                                 Instance): the four Prop Ball instances
                                 share one file
                   Masked        a cube directly in collection 'Mask', which
                                 is set to Holdout in the view layer
                                 (holdout); Inner, a cube in its child
                                 collection 'Mask inner' (not holdout:
                                 Cycles 5.0.1 makes holdouts of a holdout
                                 collection's own objects only, measured)
                   Indirect      a cube in an Indirect Only collection
                                 (invisible to the camera)
                   Rock          a cube hidden in the viewport, with a
                                 Subdivision Surface of viewport level 0 and
                                 render level 1: rendered, with 48 triangles
                   Text          a text object (a curve type: through
                                 to_mesh())
                   Spinner       a cube with keyframes (frames 1 and 3):
                                 animated
                   Empty mesh    three vertices, no face: warned about
                   Fog box       a cube with a volume material only:
                                 warned about, not a mesh
                   Ghost         a cube invisible to every ray type: nothing
                   Not rendered  a cube disabled in renders: nothing
  expected.json  for every [[mesh]] the exporter must write (by name): its
                 flags, its triangle count, the group of instances that
                 share its file, and its vertices in world space computed
                 here from the objects' own transforms (collection instance:
                 instancer . Translate(-instance offset) . object; Geometry
                 Nodes: Scatter . Translate(point) . mesh, Object Info's
                 Original space), in the mesh's vertex order; and the
                 objects that must not be exported.
  big.blend      the Volume object and one mesh of 1,002,528 triangles (a
                 708 x 708 grid of quads, smooth-shaded and wavy, with a UV
                 map and a row of sharp edges): the export's speed.
  surfaces.blend the Volume object and meshes whose materials the exporter
                 must write as [mesh.material] (surfaces_expected.json: every
                 table, the warnings, the Sphere's corner normals and UVs):
                   Plastic       a cube, Principled BSDF with every shaded
                                 input set to a constant (Base Color by an
                                 RGB node)
                   Textured      a 2 x 2 grid with a UV map, Principled Base
                                 Color from an Image Texture (tex/checker.png,
                                 4 x 4, sRGB, made here) through an identity
                                 Mapping and a UV Map node
                   Matte         a cube, Diffuse BSDF (Color, Roughness)
                   Linear matte  a grid, Diffuse BSDF Color from an Image
                                 Texture (Non-Color) through Texture
                                 Coordinate UV
                   Lamp          a cube, Emission (Color, Strength)
                   Two slots     a cube with materials 'Red' (faces 0-2) and
                                 'Blue' (faces 3-5): two [[mesh]], two PLYs
                   Sphere        a smooth UV sphere (24 x 12) with a UV map
                                 and its equator marked sharp: normals and
                                 UVs per corner (split at the seam and the
                                 sharp edge), checked against bpy's
                                 corner_normals and UVs; Principled from a
                                 node group (read through it)
                   Smooth ball   a smooth UV sphere without UV map and no
                                 sharp edge: one normal per vertex, no split
                   Mixed         a Mix Shader (factor 0.3) of a Principled
                                 and a Diffuse BSDF: warned, the Principled
                   Bumpy         a Principled BSDF with a Normal Map on
                                 Normal and Transmission Weight 0.5: warned
                   Ramp          a Color Ramp into Base Color: warned, the
                                 socket's own colour
                   Packed        a grid whose Image Texture's PNG is packed
                                 in the .blend (the file removed): written
                                 beside the PLYs
                   Missing       an Image Texture whose file does not exist:
                                 warned, magenta (as Cycles renders it)
                   Generated     an Image Texture of a generated image:
                                 warned, its colour
                   Targa         an Image Texture of a TGA file: converted to
                                 PNG beside the PLYs
                   Glowing       a Principled BSDF plus an Emission (Add
                                 Shader): the Principled with that emission
                   Hold          a Holdout shader: holdout, black table
                   Not a number  Roughness NaN: warned, Blender's 0.5
                   Bare          a cube without material: no [mesh.material]
  many.blend     the Volume object, 1,200 Geometry Nodes instances of a cube
                 (12 triangles; a 30 x 40 grid of points) and 300 of them a
                 holdout (a second scatter, Holdout on): more than 1,000
                 [[mesh]] entries, merged into one world-space mesh per set
                 of flags; and bad data: 'Broken', a cube with a vertex at
                 NaN (its three triangles there are left out), 'Flat', a
                 cube scaled 0 in z (not invertible: left out).
"""
import json
import math
import os
import sys

import bpy
import bmesh
from mathutils import Euler, Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from build_scene import cube_mesh, link, new_scene, principled  # noqa: E402


def args():
    a = sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else sys.argv[1:]
    return os.path.abspath(a[0]), os.path.abspath(a[a.index('--cloud') + 1])


def sphere_mesh(name, u, v, r):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=u, v_segments=v, radius=r)
    bm.to_mesh(me)
    bm.free()
    return me


def base_scene(cloud):
    sc = new_scene()
    r = sc.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = 64, 48, 100
    r.film_transparent = True
    sc.frame_start, sc.frame_end, sc.frame_current = 1, 3, 2
    cam = bpy.data.cameras.new('Cam')
    co = link(sc, 'Cam', cam)
    co.location = (0.0, -12.0, 2.0)
    co.rotation_euler = Euler((math.radians(82.0), 0.0, 0.0), 'XYZ')
    sc.camera = co
    sun = bpy.data.lights.new('Sun', 'SUN')
    sun.energy = 3.0
    link(sc, 'Sun', sun).rotation_euler = Euler((0.5, 0.3, 0.0), 'XYZ')
    w = bpy.data.worlds.new('World')
    w.use_nodes = True
    w.node_tree.nodes['Background'].inputs['Color'].default_value = (0.03, 0.03, 0.04, 1.0)
    sc.world = w
    vol = bpy.data.volumes.new('Cloud')
    vol.filepath = cloud
    vol.materials.append(principled('Cloud material', Density=4.0))
    link(sc, 'Cloud', vol).location = (0.0, 1.0, 0.5)
    return sc


def world_vertices(me, m):
    return [list(m @ v.co) for v in me.vertices]


def main():
    out, cloud = args()
    os.makedirs(out, exist_ok=True)
    sc = base_scene(cloud)
    vl = sc.view_layers[0]
    expected = {}

    def expect(name, me, m, tris, share, holdout=False, catcher=False, off=()):
        expected[name] = {'holdout': holdout, 'shadow_catcher': catcher,
                          'visibility_off': sorted(off), 'triangles': tris, 'share': share,
                          'world': world_vertices(me, m) if me is not None else None}

    # Ground: a 4 x 4 quad, placed and scaled to 8 x 8.
    gme = bpy.data.meshes.new('Ground')
    gme.from_pydata([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [], [(0, 1, 2, 3)])
    ground = link(sc, 'Ground', gme)
    ground.location = (0.0, 0.0, -1.0)
    ground.rotation_euler = (0.0, 0.0, math.radians(10.0))
    ground.scale = (2.0, 2.0, 1.0)
    ground.is_shadow_catcher = True

    bme = sphere_mesh('Ball', 32, 16, 0.5)
    ball = link(sc, 'Ball', bme)
    ball.location = (1.5, -1.0, 0.2)
    ball.rotation_euler = Euler((math.radians(10), math.radians(20), math.radians(30)), 'XYZ')
    ball.scale = (1.0, 1.2, 0.8)
    ball.is_holdout = True
    copy = link(sc, 'Ball copy', bme)
    copy.location = (-1.5, -1.0, 0.2)
    copy.visible_shadow = False

    props = bpy.data.collections.new('Props')
    sc.collection.children.link(props)
    props.instance_offset = (0.1, 0.2, 0.0)
    pme = sphere_mesh('Prop Ball', 24, 12, 0.3)
    prop = bpy.data.objects.new('Prop Ball', pme)
    props.objects.link(prop)
    prop.location = (0.3, 0.0, 0.0)
    prop.visible_glossy = False
    prop.is_shadow_catcher = True
    vl.layer_collection.children['Props'].exclude = True
    inst = bpy.data.objects.new('Props A', None)
    sc.collection.objects.link(inst)
    inst.instance_type = 'COLLECTION'
    inst.instance_collection = props
    inst.location = (-3.0, 2.0, 0.5)
    inst.rotation_euler = (0.0, 0.0, math.radians(45.0))
    inst.scale = (0.8, 0.8, 0.8)

    pts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    sme = bpy.data.meshes.new('Scatter points')
    sme.from_pydata(pts, [], [])
    scatter = link(sc, 'Scatter', sme)
    scatter.location = (2.0, 2.0, 0.0)
    scatter.rotation_euler = (0.0, 0.0, math.radians(30.0))
    ng = bpy.data.node_groups.new('Scatter', 'GeometryNodeTree')
    ng.interface.new_socket('Geometry', in_out='INPUT', socket_type='NodeSocketGeometry')
    ng.interface.new_socket('Geometry', in_out='OUTPUT', socket_type='NodeSocketGeometry')
    gi, go = ng.nodes.new('NodeGroupInput'), ng.nodes.new('NodeGroupOutput')
    iop = ng.nodes.new('GeometryNodeInstanceOnPoints')
    oi = ng.nodes.new('GeometryNodeObjectInfo')
    oi.inputs['Object'].default_value = prop
    oi.inputs['As Instance'].default_value = True
    ng.links.new(gi.outputs[0], iop.inputs['Points'])
    ng.links.new(oi.outputs['Geometry'], iop.inputs['Instance'])
    ng.links.new(iop.outputs['Instances'], go.inputs[0])
    scatter.modifiers.new('Scatter', 'NODES').node_group = ng

    mask = bpy.data.collections.new('Mask')
    sc.collection.children.link(mask)
    inner = bpy.data.collections.new('Mask inner')
    mask.children.link(inner)
    masked = bpy.data.objects.new('Masked', cube_mesh('Masked', 0.5))
    mask.objects.link(masked)
    masked.location = (3.0, 0.0, -0.5)
    inner_o = bpy.data.objects.new('Inner', cube_mesh('Inner', 0.5))
    inner.objects.link(inner_o)
    inner_o.location = (-3.0, 0.0, -0.5)
    vl.layer_collection.children['Mask'].holdout = True
    ind = bpy.data.collections.new('Indirect only')
    sc.collection.children.link(ind)
    indirect = bpy.data.objects.new('Indirect', cube_mesh('Indirect', 0.4))
    ind.objects.link(indirect)
    indirect.location = (0.0, 3.0, -0.5)
    vl.layer_collection.children['Indirect only'].indirect_only = True

    rock = link(sc, 'Rock', cube_mesh('Rock', 0.6))
    rock.location = (-1.0, 1.0, -0.6)
    sub = rock.modifiers.new('Subdivision', 'SUBSURF')
    sub.levels = 0
    sub.render_levels = 1
    rock.hide_viewport = True

    txt = bpy.data.curves.new('Text', 'FONT')
    txt.body = 'vdb'
    txt.extrude = 0.05
    text = link(sc, 'Text', txt)
    text.location = (-2.0, -2.0, 1.5)
    text.rotation_euler = (math.radians(90.0), 0.0, 0.0)

    spin = link(sc, 'Spinner', cube_mesh('Spinner', 0.3))
    spin.location = (0.0, -2.0, 1.2)
    for f, angle in ((1, 0.0), (3, 90.0)):
        spin.rotation_euler = (0.0, 0.0, math.radians(angle))
        spin.keyframe_insert('rotation_euler', frame=f)

    eme = bpy.data.meshes.new('Empty mesh')
    eme.from_pydata(pts, [], [])
    link(sc, 'Empty mesh', eme).location = (0.0, 0.0, 3.0)
    fog = link(sc, 'Fog box', cube_mesh('Fog box', 1.0))
    fog.location = (0.0, 4.0, 1.0)
    fog.data.materials.append(principled('Fog material', Density=0.5))
    ghost = link(sc, 'Ghost', cube_mesh('Ghost', 0.5))
    for k in ('camera', 'diffuse', 'glossy', 'transmission', 'volume_scatter', 'shadow'):
        setattr(ghost, 'visible_' + k, False)
    link(sc, 'Not rendered', cube_mesh('Not rendered', 0.5)).hide_render = True

    sc.frame_set(2)
    mw = {o.name: o.matrix_world.copy() for o in sc.objects}
    expect('Ground', gme, mw['Ground'], 2, 'Ground', catcher=True)
    expect('Ball', bme, mw['Ball'], 960, 'Ball', holdout=True)
    expect('Ball copy', bme, mw['Ball copy'], 960, 'Ball', off=['shadow'])
    a = mw['Props A'] @ Matrix.Translation(-Vector(props.instance_offset)) @ mw['Prop Ball']
    expect('Props A/Prop Ball #1', pme, a, 528, 'Prop Ball', catcher=True, off=['glossy'])
    for i, p in enumerate(pts):
        expect(f'Scatter/Prop Ball #{i + 1}', pme, mw['Scatter'] @ Matrix.Translation(p), 528,
               'Prop Ball', catcher=True, off=['glossy'])
    expect('Masked', masked.data, mw['Masked'], 12, 'Masked', holdout=True)
    expect('Inner', inner_o.data, mw['Inner'], 12, 'Inner')
    expect('Indirect', indirect.data, mw['Indirect'], 12, 'Indirect', off=['camera'])
    expect('Rock', None, mw['Rock'], 48, 'Rock')
    expect('Text', None, mw['Text'], None, 'Text')
    expect('Spinner', spin.data, mw['Spinner'], 12, 'Spinner')
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'meshes.blend'))
    with open(os.path.join(out, 'expected.json'), 'w') as f:
        json.dump({'meshes': expected,
                   'absent': ['Empty mesh', 'Fog box', 'Ghost', 'Not rendered', 'Cloud',
                              'Scatter', 'Props A']}, f)

    # big.blend: a 708 x 708 grid of quads, 1,002,528 triangles, the
    # exporter's most expensive case: smooth-shaded, a UV map, waves and a
    # row of sharp edges (corner normals, its vertices split there).
    sc = base_scene(cloud)
    me = bpy.data.meshes.new('Big')
    bm = bmesh.new()
    bm.loops.layers.uv.new('UVMap')
    bmesh.ops.create_grid(bm, x_segments=708, y_segments=708, size=3.0, calc_uvs=True)
    for v in bm.verts:
        v.co.z = 0.2 * math.sin(3.0 * v.co.x) * math.cos(2.0 * v.co.y)
    for e in bm.edges:
        if all(abs(v.co.y) < 1e-6 for v in e.verts):
            e.smooth = False
    for f in bm.faces:
        f.smooth = True
    bm.to_mesh(me)
    bm.free()
    assert me.normals_domain == 'CORNER', me.normals_domain
    big = link(sc, 'Big', me)
    big.location = (0.0, 2.0, -1.0)
    print('big mesh:', len(me.vertices), 'vertices', len(me.polygons), 'quads')
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'big.blend'))

    # many.blend: 1,500 instances, and bad data.
    sc = base_scene(cloud)
    cube = bpy.data.objects.new('Pebble', cube_mesh('Pebble', 0.05))
    sc.collection.objects.link(cube)
    cube.hide_render = True
    for name, nx, ny, holdout in (('Scatter', 30, 40, False), ('Holdouts', 15, 20, True)):
        grid = bpy.data.meshes.new(name)
        grid.from_pydata([(0.1 * i, 0.1 * j, 0.0) for i in range(nx) for j in range(ny)], [],
                         [])
        o = link(sc, name, grid)
        o.location = (-1.5, -1.0, -1.0 if not holdout else 1.5)
        o.is_holdout = holdout
        ng = bpy.data.node_groups.new(name, 'GeometryNodeTree')
        ng.interface.new_socket('Geometry', in_out='INPUT', socket_type='NodeSocketGeometry')
        ng.interface.new_socket('Geometry', in_out='OUTPUT', socket_type='NodeSocketGeometry')
        gi, go = ng.nodes.new('NodeGroupInput'), ng.nodes.new('NodeGroupOutput')
        iop = ng.nodes.new('GeometryNodeInstanceOnPoints')
        oi = ng.nodes.new('GeometryNodeObjectInfo')
        oi.inputs['Object'].default_value = cube
        oi.inputs['As Instance'].default_value = True
        ng.links.new(gi.outputs[0], iop.inputs['Points'])
        ng.links.new(oi.outputs['Geometry'], iop.inputs['Instance'])
        ng.links.new(iop.outputs['Instances'], go.inputs[0])
        o.modifiers.new(name, 'NODES').node_group = ng
    broken = link(sc, 'Broken', cube_mesh('Broken', 0.5))
    broken.data.vertices[0].co = (float('nan'), 0.0, 0.0)
    link(sc, 'Flat', cube_mesh('Flat', 0.5)).scale = (1.0, 1.0, 0.0)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'many.blend'))

    surfaces(out, cloud)
    print('built', out)


# ---------------------------------------------------------------- surfaces

def material(name, shader, **inputs):
    """A material with one shader node (type `shader`, named as Blender
    names it) into the output's Surface; returns (material, node tree,
    shader node)."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    sh = nt.nodes.new(shader)
    for k, v in inputs.items():
        sh.inputs[k].default_value = v
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(sh.outputs[0], out.inputs['Surface'])
    return m, nt, sh


def grid_mesh(name, uv=True):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    if uv:
        bm.loops.layers.uv.new('UVMap')
    bmesh.ops.create_grid(bm, x_segments=2, y_segments=2, size=1.0, calc_uvs=uv)
    bm.to_mesh(me)
    bm.free()
    return me


def write_png(path, w, h, rgba):
    """A PNG of w x h pixels (rgba: rows from the bottom, as Blender's
    pixels) written by Blender."""
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=True)
    img.pixels = [x for p in rgba for x in p]
    img.filepath_raw = path
    img.file_format = 'PNG'
    img.save()
    bpy.data.images.remove(img)


def r7(v):
    return [float('%.7g' % float(x)) for x in v]


def surfaces(out, cloud):
    sc = base_scene(cloud)
    tex = os.path.join(out, 'tex')
    os.makedirs(tex, exist_ok=True)
    checker = os.path.join(tex, 'checker.png')
    write_png(checker, 4, 4, [((i + j) % 2 * 0.8 + 0.1, 0.5, (i * 4 + j) / 15.0, 1.0)
                              for i in range(4) for j in range(4)])
    packed_png = os.path.join(tex, 'packed.png')
    write_png(packed_png, 2, 2, [(1, 0, 0, 1), (0, 1, 0, 1), (0, 0, 1, 1), (1, 1, 1, 1)])
    exp, warns = {}, []

    # Plastic: every shaded Principled input a constant; Base Color from an RGB node.
    m, nt, p = material('Plastic', 'ShaderNodeBsdfPrincipled', **{
        'Roughness': 0.3, 'Metallic': 0.1, 'IOR': 1.45, 'Specular IOR Level': 0.6,
        'Specular Tint': (1.0, 0.9, 0.8, 1.0), 'Emission Color': (1.0, 0.5, 0.25, 1.0),
        'Emission Strength': 0.5})
    rgbn = nt.nodes.new('ShaderNodeRGB')
    rgbn.outputs[0].default_value = (0.2, 0.4, 0.6, 1.0)
    nt.links.new(rgbn.outputs[0], p.inputs['Base Color'])
    o = link(sc, 'Plastic', cube_mesh('Plastic', 0.5))
    o.data.materials.append(m)
    exp['Plastic'] = {'type': 'principled', 'base_color': r7([0.2, 0.4, 0.6]),
                      'roughness': 0.3, 'metallic': 0.1, 'ior': 1.45,
                      'specular_ior_level': 0.6, 'specular_tint': r7([1.0, 0.9, 0.8]),
                      'emission_color': [1.0, 0.5, 0.25], 'emission_strength': 0.5}

    # Textured: Image Texture (sRGB) <- Mapping (identity) <- UV Map.
    m, nt, p = material('Textured', 'ShaderNodeBsdfPrincipled', Roughness=0.6)
    t = nt.nodes.new('ShaderNodeTexImage')
    t.image = bpy.data.images.load(checker)
    mp = nt.nodes.new('ShaderNodeMapping')
    uvn = nt.nodes.new('ShaderNodeUVMap')
    uvn.uv_map = 'UVMap'
    nt.links.new(uvn.outputs['UV'], mp.inputs['Vector'])
    nt.links.new(mp.outputs['Vector'], t.inputs['Vector'])
    nt.links.new(t.outputs['Color'], p.inputs['Base Color'])
    o = link(sc, 'Textured', grid_mesh('Textured'))
    o.location = (0.0, 0.0, -1.0)
    o.data.materials.append(m)
    exp['Textured'] = {'type': 'principled',
                       'base_color_texture': {'file': checker, 'colorspace': 'srgb'},
                       'roughness': 0.6, 'metallic': 0.0, 'ior': 1.5, 'specular_ior_level': 0.5,
                       'specular_tint': [1.0, 1.0, 1.0], 'emission_color': [1.0, 1.0, 1.0],
                       'emission_strength': 0.0}

    m, nt, d = material('Matte', 'ShaderNodeBsdfDiffuse', Color=(0.5, 0.6, 0.7, 1.0),
                        Roughness=0.2)
    o = link(sc, 'Matte', cube_mesh('Matte', 0.5))
    o.location = (1.0, 0.0, 0.0)
    o.data.materials.append(m)
    exp['Matte'] = {'type': 'diffuse', 'color': r7([0.5, 0.6, 0.7]), 'roughness': 0.2}

    m, nt, d = material('Linear matte', 'ShaderNodeBsdfDiffuse')
    t = nt.nodes.new('ShaderNodeTexImage')
    t.image = bpy.data.images.load(checker, check_existing=False)
    t.image.colorspace_settings.name = 'Non-Color'
    tc = nt.nodes.new('ShaderNodeTexCoord')
    nt.links.new(tc.outputs['UV'], t.inputs['Vector'])
    nt.links.new(t.outputs['Color'], d.inputs['Color'])
    o = link(sc, 'Linear matte', grid_mesh('Linear matte'))
    o.location = (2.0, 0.0, -1.0)
    o.data.materials.append(m)
    exp['Linear matte'] = {'type': 'diffuse',
                           'color_texture': {'file': checker, 'colorspace': 'linear'},
                           'roughness': 0.0}

    m, nt, e = material('Lamp', 'ShaderNodeEmission', Color=(1.0, 0.8, 0.6, 1.0), Strength=4.0)
    o = link(sc, 'Lamp', cube_mesh('Lamp', 0.2))
    o.location = (-1.0, 0.0, 1.0)
    o.data.materials.append(m)
    exp['Lamp'] = {'type': 'emission', 'color': r7([1.0, 0.8, 0.6]), 'strength': 4.0}

    me = cube_mesh('Two slots', 0.5)
    for name, col in (('Red', (0.8, 0.1, 0.1, 1.0)), ('Blue', (0.1, 0.1, 0.8, 1.0))):
        me.materials.append(material(name, 'ShaderNodeBsdfDiffuse', Color=col)[0])
    for i, poly in enumerate(me.polygons):
        poly.material_index = 0 if i < 3 else 1
    o = link(sc, 'Two slots', me)
    o.location = (-2.0, 0.0, 0.0)
    exp['Two slots [Red]'] = {'type': 'diffuse', 'color': r7([0.8, 0.1, 0.1]), 'roughness': 0.0}
    exp['Two slots [Blue]'] = {'type': 'diffuse', 'color': r7([0.1, 0.1, 0.8]),
                               'roughness': 0.0}

    # Sphere: smooth, UVs, the equator sharp; its material in a node group.
    me = bpy.data.meshes.new('Sphere')
    bm = bmesh.new()
    bm.loops.layers.uv.new('UVMap')
    bmesh.ops.create_uvsphere(bm, u_segments=24, v_segments=12, radius=0.5, calc_uvs=True)
    bm.to_mesh(me)
    bm.free()
    for poly in me.polygons:
        poly.use_smooth = True
    for ed in me.edges:
        a, b = (me.vertices[v].co for v in ed.vertices)
        if abs(a.z) < 1e-6 and abs(b.z) < 1e-6:
            ed.use_edge_sharp = True
    me.update()
    assert me.normals_domain == 'CORNER', me.normals_domain
    ng = bpy.data.node_groups.new('Shiny group', 'ShaderNodeTree')
    ng.interface.new_socket('Tint', in_out='INPUT', socket_type='NodeSocketColor')
    ng.interface.new_socket('Shader', in_out='OUTPUT', socket_type='NodeSocketShader')
    gi, go = ng.nodes.new('NodeGroupInput'), ng.nodes.new('NodeGroupOutput')
    gp = ng.nodes.new('ShaderNodeBsdfPrincipled')
    gp.inputs['Roughness'].default_value = 0.15
    gp.inputs['Metallic'].default_value = 1.0
    ng.links.new(gi.outputs['Tint'], gp.inputs['Base Color'])
    ng.links.new(gp.outputs['BSDF'], go.inputs['Shader'])
    m = bpy.data.materials.new('Shiny')
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    g = nt.nodes.new('ShaderNodeGroup')
    g.node_tree = ng
    g.inputs['Tint'].default_value = (0.9, 0.6, 0.3, 1.0)
    out_n = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(g.outputs['Shader'], out_n.inputs['Surface'])
    me.materials.append(m)
    o = link(sc, 'Sphere', me)
    o.location = (0.0, 2.0, 1.0)
    exp['Sphere'] = {'type': 'principled', 'base_color': r7([0.9, 0.6, 0.3]), 'roughness': 0.15,
                     'metallic': 1.0, 'ior': 1.5, 'specular_ior_level': 0.5,
                     'specular_tint': [1.0, 1.0, 1.0], 'emission_color': [1.0, 1.0, 1.0],
                     'emission_strength': 0.0}
    # Blender's own corners: per loop triangle, each corner's position,
    # normal (corner_normals) and UV.
    me.calc_loop_triangles()
    corners = []
    uvl = me.uv_layers['UVMap'].uv
    for lt in me.loop_triangles:
        for v, lp in zip(lt.vertices, lt.loops):
            corners.append(list(me.vertices[v].co) + list(me.corner_normals[lp].vector) +
                           list(uvl[lp].vector))
    sphere_corners = corners

    me = sphere_mesh('Smooth ball', 16, 8, 0.4)
    for poly in me.polygons:
        poly.use_smooth = True
    o = link(sc, 'Smooth ball', me)
    o.location = (1.5, 2.0, 1.0)
    ball_normals = [list(n.vector) for n in me.vertex_normals]
    ball_vertices = len(me.vertices)
    exp['Smooth ball'] = None

    # Mixed: a Mix Shader.
    m, nt, p = material('Mix material', 'ShaderNodeBsdfPrincipled', Roughness=0.25)
    p.name = 'Glossy part'
    out_n = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'][0]
    dif = nt.nodes.new('ShaderNodeBsdfDiffuse')
    dif.name = 'Matte part'
    mix = nt.nodes.new('ShaderNodeMixShader')
    mix.name = 'Mix Shader'
    mix.inputs['Factor'].default_value = 0.3
    nt.links.new(p.outputs[0], mix.inputs[1])
    nt.links.new(dif.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out_n.inputs['Surface'])
    o = link(sc, 'Mixed', cube_mesh('Mixed', 0.5))
    o.location = (-3.0, 1.0, 0.0)
    o.data.materials.append(m)
    warns.append("mesh object 'Mixed': material 'Mix material' node 'Mix Shader' (Mix Shader) "
                 "mixes 'Glossy part' and 'Matte part' by its Factor 0.3")
    exp['Mixed'] = {'type': 'principled', 'base_color': r7([0.8, 0.8, 0.8]), 'roughness': 0.25,
                    'metallic': 0.0, 'ior': 1.5, 'specular_ior_level': 0.5,
                    'specular_tint': [1.0, 1.0, 1.0], 'emission_color': [1.0, 1.0, 1.0],
                    'emission_strength': 0.0}

    # Bumpy: a Normal Map on Normal, Transmission Weight 0.5.
    m, nt, p = material('Bump material', 'ShaderNodeBsdfPrincipled',
                        **{'Transmission Weight': 0.5})
    nm = nt.nodes.new('ShaderNodeNormalMap')
    nm.name = 'Normal Map'
    nt.links.new(nm.outputs['Normal'], p.inputs['Normal'])
    o = link(sc, 'Bumpy', cube_mesh('Bumpy', 0.5))
    o.location = (-3.0, 2.0, 0.0)
    o.data.materials.append(m)
    warns.append("mesh object 'Bumpy': material 'Bump material' node 'Normal Map' (Normal Map) "
                 "drives 'Normal' of node 'Principled BSDF'")
    warns.append("mesh object 'Bumpy': material 'Bump material' node 'Principled BSDF': "
                 "'Transmission Weight' is 0.5")
    exp['Bumpy'] = {'type': 'principled', 'base_color': r7([0.8, 0.8, 0.8]), 'roughness': 0.5,
                    'metallic': 0.0, 'ior': 1.5, 'specular_ior_level': 0.5,
                    'specular_tint': [1.0, 1.0, 1.0], 'emission_color': [1.0, 1.0, 1.0],
                    'emission_strength': 0.0}

    # Ramp: a Color Ramp into Base Color: the socket's own colour.
    m, nt, p = material('Ramp material', 'ShaderNodeBsdfPrincipled',
                        **{'Base Color': (0.3, 0.5, 0.1, 1.0)})
    ramp = nt.nodes.new('ShaderNodeValToRGB')
    ramp.name = 'Color Ramp'
    nt.links.new(ramp.outputs['Color'], p.inputs['Base Color'])
    o = link(sc, 'Ramp', cube_mesh('Ramp', 0.5))
    o.location = (-3.0, 3.0, 0.0)
    o.data.materials.append(m)
    warns.append("mesh object 'Ramp': material 'Ramp material' node 'Color Ramp' (Color Ramp) "
                 "drives 'Base Color' of node 'Principled BSDF'")
    exp['Ramp'] = dict(exp['Bumpy'], base_color=r7([0.3, 0.5, 0.1]))

    # Packed: the PNG packed into the .blend, then removed from disk.
    m, nt, p = material('Packed material', 'ShaderNodeBsdfPrincipled')
    t = nt.nodes.new('ShaderNodeTexImage')
    t.image = bpy.data.images.load(packed_png)
    t.image.pack()
    nt.links.new(t.outputs['Color'], p.inputs['Base Color'])
    o = link(sc, 'Packed', grid_mesh('Packed'))
    o.location = (3.0, 0.0, -1.0)
    o.data.materials.append(m)
    with open(packed_png, 'rb') as f:
        packed_hex = f.read().hex()
    exp['Packed'] = dict(exp['Textured'], roughness=0.5, base_color_texture={
        'file': 'surfaces_meshes/packed.png', 'colorspace': 'srgb'})

    # Missing and generated images.
    m, nt, p = material('Missing material', 'ShaderNodeBsdfPrincipled')
    t = nt.nodes.new('ShaderNodeTexImage')
    t.name = 'Lost texture'
    img = bpy.data.images.new('gone.png', 4, 4)
    img.source = 'FILE'
    img.filepath = os.path.join(tex, 'gone.png')
    t.image = img
    nt.links.new(t.outputs['Color'], p.inputs['Base Color'])
    o = link(sc, 'Missing', grid_mesh('Missing'))
    o.location = (4.0, 0.0, -1.0)
    o.data.materials.append(m)
    warns.append("mesh object 'Missing': material 'Missing material' node 'Lost texture' "
                 "(Image Texture): image 'gone.png' file")
    exp['Missing'] = dict(exp['Packed'], base_color=[1.0, 0.0, 1.0])
    exp['Missing'].pop('base_color_texture')

    m, nt, p = material('Generated material', 'ShaderNodeBsdfPrincipled')
    t = nt.nodes.new('ShaderNodeTexImage')
    t.name = 'Blank texture'
    t.image = bpy.data.images.new('blank', 8, 8, alpha=False)
    t.image.generated_color = (0.25, 0.5, 0.75, 1.0)
    nt.links.new(t.outputs['Color'], p.inputs['Base Color'])
    o = link(sc, 'Generated', grid_mesh('Generated'))
    o.location = (5.0, 0.0, -1.0)
    o.data.materials.append(m)
    warns.append("mesh object 'Generated': material 'Generated material' node 'Blank texture' "
                 "(Image Texture): image 'blank' is generated in Blender")
    exp['Generated'] = dict(exp['Missing'], base_color=r7([0.25, 0.5, 0.75]))

    # Targa: a TGA file, converted to PNG beside the PLYs.
    img = bpy.data.images.new('grey.tga', 2, 2)
    img.pixels = [0.5, 0.5, 0.5, 1.0] * 4
    img.filepath_raw = os.path.join(tex, 'grey.tga')
    img.file_format = 'TARGA'
    img.save()
    bpy.data.images.remove(img)
    m, nt, p = material('Targa material', 'ShaderNodeBsdfPrincipled')
    t = nt.nodes.new('ShaderNodeTexImage')
    t.image = bpy.data.images.load(os.path.join(tex, 'grey.tga'))
    nt.links.new(t.outputs['Color'], p.inputs['Base Color'])
    o = link(sc, 'Targa', grid_mesh('Targa'))
    o.location = (6.0, 0.0, -1.0)
    o.data.materials.append(m)
    exp['Targa'] = dict(exp['Packed'], base_color_texture={
        'file': 'surfaces_meshes/grey.png', 'colorspace': 'srgb'})

    # Glowing: a Principled BSDF plus an Emission (Add Shader): one table.
    m, nt, p = material('Glow material', 'ShaderNodeBsdfPrincipled', Roughness=0.2)
    out_n = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'][0]
    em = nt.nodes.new('ShaderNodeEmission')
    em.inputs['Color'].default_value = (1.0, 0.5, 0.25, 1.0)
    em.inputs['Strength'].default_value = 3.0
    add = nt.nodes.new('ShaderNodeAddShader')
    nt.links.new(p.outputs[0], add.inputs[0])
    nt.links.new(em.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], out_n.inputs['Surface'])
    o = link(sc, 'Glowing', cube_mesh('Glowing', 0.3))
    o.location = (1.0, -2.0, 0.0)
    o.data.materials.append(m)
    exp['Glowing'] = dict(exp['Bumpy'], roughness=0.2, emission_color=[1.0, 0.5, 0.25],
                          emission_strength=3.0)

    # Hold: a Holdout shader: a holdout, black to the other rays.
    o = link(sc, 'Hold', cube_mesh('Hold', 0.3))
    o.location = (2.0, -2.0, 0.0)
    o.data.materials.append(material('Holdout material', 'ShaderNodeHoldout')[0])
    exp['Hold'] = {'type': 'diffuse', 'color': [0.0, 0.0, 0.0], 'roughness': 0.0}

    # Not a number: Roughness NaN: warned, Blender's default.
    o = link(sc, 'Not a number', cube_mesh('Not a number', 0.3))
    o.location = (3.0, -2.0, 0.0)
    o.data.materials.append(material('NaN material', 'ShaderNodeBsdfPrincipled',
                                     Roughness=float('nan'))[0])
    warns.append("mesh object 'Not a number': material 'NaN material' node 'Principled BSDF': "
                 "'Roughness' is nan; Blender's default 0.5 used")
    exp['Not a number'] = dict(exp['Bumpy'])

    o = link(sc, 'Bare', cube_mesh('Bare', 0.3))
    o.location = (0.0, -2.0, 0.0)
    exp['Bare'] = None

    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, 'surfaces.blend'))
    os.remove(packed_png)
    with open(os.path.join(out, 'surfaces_expected.json'), 'w') as f:
        json.dump({'materials': exp, 'warnings': warns, 'sphere_corners': sphere_corners,
                   'ball_normals': ball_normals, 'ball_vertices': ball_vertices,
                   'packed_png': packed_hex, 'texture_uvs': uv_of('Textured')}, f)


def uv_of(name):
    """Per loop triangle corner: position and UV of mesh `name`."""
    me = bpy.data.meshes[name]
    me.calc_loop_triangles()
    uvl = me.uv_layers.active.uv
    return [list(me.vertices[v].co) + list(uvl[lp].vector)
            for lt in me.loop_triangles for v, lp in zip(lt.vertices, lt.loops)]


if __name__ == '__main__':
    main()
    sys.stdout.flush()
    os._exit(0)
