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
                 708 x 708 grid of quads): the export's speed.
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

    # big.blend: a 708 x 708 grid of quads, 1,002,528 triangles.
    sc = base_scene(cloud)
    me = bpy.data.meshes.new('Big')
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=708, y_segments=708, size=3.0)
    bm.to_mesh(me)
    bm.free()
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
    print('built', out)


if __name__ == '__main__':
    main()
    sys.stdout.flush()
    os._exit(0)
