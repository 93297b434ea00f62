"""Meshes as the exporter writes them: which objects are surfaces, their
arrays read from Blender (numpy), instances merged into world space,
vertices split where their corners differ, and the binary PLY files."""

import os

from .util import ExportError

# Object.visible_<ray> flags (Object > Visibility > Ray Visibility).
RAY_VISIBILITY = ('visible_camera', 'visible_diffuse', 'visible_glossy', 'visible_transmission',
                  'visible_volume_scatter', 'visible_shadow')


# Object types whose evaluated geometry Cycles renders as a surface, which
# the exporter writes as meshes (curves, surfaces, metaballs and text through
# Object.to_mesh()).
SURFACE_TYPES = ('MESH', 'CURVE', 'SURFACE', 'META', 'FONT')
CURVE_TYPES = ('CURVE', 'SURFACE', 'META', 'FONT')
OBJECT_KINDS = {'MESH': 'mesh', 'META': 'metaball', 'CURVE': 'curve', 'SURFACE': 'surface',
                'FONT': 'text', 'CURVES': 'hair curves', 'POINTCLOUD': 'point cloud',
                'GPENCIL': 'grease pencil', 'GREASEPENCIL': 'grease pencil'}
# The [[mesh]] visibility keys, Blender's Object.visible_<key>.
VISIBILITY_KEYS = ('camera', 'shadow', 'diffuse', 'glossy', 'transmission', 'volume_scatter')
# More mesh instances than this are merged into world-space meshes: each
# [[mesh]] entry takes about 400 bytes and vdbphoton reads scene files of
# at most 1 MiB.
MAX_MESH_ENTRIES = 1000
MAX_MERGED_TRIANGLES = 200_000_000
# Modifiers that make a mesh change over time by themselves.
TIME_MODIFIERS = ('CLOTH', 'SOFT_BODY', 'OCEAN', 'EXPLODE', 'DYNAMIC_PAINT', 'MESH_CACHE',
                  'MESH_SEQUENCE_CACHE', 'WAVE', 'COLLISION', 'PARTICLE_SYSTEM')


def is_fluid_domain(o):
    """A fluid domain Blender renders as a domain (the exporter's volumes,
    or a liquid it warns about), not as its mesh."""
    return any(m.type == 'FLUID' and m.fluid_type == 'DOMAIN' and m.show_render
               for m in getattr(o, 'modifiers', []))


def has_animation(idblock):
    ad = getattr(idblock, 'animation_data', None)
    return ad is not None and (ad.action is not None or len(ad.drivers) > 0 or
                               len(ad.nla_tracks) > 0)


def node_group_uses_time(ng, seen=None):
    seen = set() if seen is None else seen
    if ng is None or ng.name_full in seen:
        return False
    seen.add(ng.name_full)
    if has_animation(ng):
        return True
    for n in ng.nodes:
        if n.bl_idname in ('GeometryNodeInputSceneTime', 'GeometryNodeSimulationInput',
                           'GeometryNodeSimulationOutput'):
            return True
        if getattr(n, 'node_tree', None) is not None and node_group_uses_time(n.node_tree, seen):
            return True
    return False


def is_animated(o):
    """Whether object `o` (or a parent) may move or change over frames:
    animation or drivers on it, its data or shape keys, a time-dependent
    modifier, or Geometry Nodes reading the time."""
    while o is not None:
        if has_animation(o) or has_animation(getattr(o, 'data', None)):
            return True
        keys = getattr(getattr(o, 'data', None), 'shape_keys', None)
        if keys is not None and has_animation(keys):
            return True
        for m in getattr(o, 'modifiers', []):
            if m.type in TIME_MODIFIERS or (m.type == 'NODES' and
                                            node_group_uses_time(m.node_group)):
                return True
        o = o.parent
    return False


def slot_materials(ob):
    """The materials of evaluated object `ob`'s slots, as Cycles takes them
    (None for an empty slot); [] without slots."""
    mats = [s.material for s in getattr(ob, 'material_slots', [])]
    if not mats and getattr(ob, 'type', None) == 'MESH' and ob.data is not None:
        mats = list(ob.data.materials)
    return mats


def read_mesh_arrays(me):
    """Mesh `me`'s arrays, read in bulk: vertex positions (n, 3), loop
    triangles' vertices and corners (m, 3), their material indices (m,),
    the corners' vertices (corners,), the normals Blender shades with: None
    (every face flat), ('point', (n, 3)
    vertex normals: smooth without sharp edges) or ('corner', (corners, 3):
    Blender 4.1+'s corner_normals, flat faces' own normal, split and custom
    normals), and the active render UV map (corners, 2) and its name, or
    None, None."""
    import numpy as np
    nv, nt, nl = len(me.vertices), len(me.loop_triangles), len(me.loops)
    co = np.empty(nv * 3, dtype=np.float32)
    me.vertices.foreach_get('co', co)
    loops = np.empty(nt * 3, dtype=np.int32)
    me.loop_triangles.foreach_get('loops', loops)
    attrs = getattr(me, 'attributes', None)
    cv = attrs.get('.corner_vert') if attrs is not None else None
    if cv is not None and cv.domain == 'CORNER' and len(cv.data) == nl:
        # Blender 4+: the corners' vertices, read raw (3 x faster).
        corner_vert = np.empty(nl, dtype=np.int32)
        cv.data.foreach_get('value', corner_vert)
    else:
        corner_vert = np.empty(nl, dtype=np.int32)
        me.loops.foreach_get('vertex_index', corner_vert)
    tri = corner_vert[loops]
    if hasattr(me, 'loop_triangle_polygons'):
        ltp = np.empty(nt, dtype=np.int32)
        me.loop_triangle_polygons.foreach_get('value', ltp)
        ma = attrs.get('material_index')
        if ma is not None and ma.domain == 'FACE' and ma.data_type == 'INT':
            pm = np.empty(len(me.polygons), dtype=np.int32)
            ma.data.foreach_get('value', pm)
            mi = pm[ltp]
        else:
            mi = np.zeros(nt, dtype=np.int32)
    else:
        mi = np.empty(nt, dtype=np.int32)
        me.loop_triangles.foreach_get('material_index', mi)
    normals = None
    if hasattr(me, 'normals_domain'):  # Blender 4.1+
        dom = me.normals_domain
        if dom == 'POINT':
            n = np.empty(nv * 3, dtype=np.float32)
            me.vertex_normals.foreach_get('vector', n)
            normals = ('point', n.reshape(-1, 3))
        elif dom == 'CORNER':
            n = np.empty(nl * 3, dtype=np.float32)
            me.corner_normals.foreach_get('vector', n)
            normals = ('corner', n.reshape(-1, 3))
    else:  # Blender 3.x: split normals (flat faces get their face normal)
        smooth = np.zeros(len(me.polygons), dtype=bool)
        me.polygons.foreach_get('use_smooth', smooth)
        if smooth.any():
            me.calc_normals_split()
            n = np.empty(nl * 3, dtype=np.float32)
            me.loops.foreach_get('normal', n)
            normals = ('corner', n.reshape(-1, 3))
    uv, uv_name = None, None
    layer = next((u for u in me.uv_layers if u.active_render), None)
    if layer is not None and nl:
        uv = np.empty(nl * 2, dtype=np.float32)
        if hasattr(layer, 'uv'):
            layer.uv.foreach_get('vector', uv)
        else:
            layer.data.foreach_get('uv', uv)
        uv, uv_name = uv.reshape(-1, 2), layer.name
    return (co.reshape(-1, 3), tri.reshape(-1, 3), loops.reshape(-1, 3), corner_vert, mi,
            normals, uv, uv_name)


def merge_world(items):
    """Meshes (self.meshes parts) through their matrices, merged into one
    world-space mesh. Normals go through the inverse transpose; a mesh
    without normals among ones with them gets its face normals (its
    triangles' corners split), one without UVs (0, 0)."""
    import numpy as np
    with_n = any(d['n'] is not None for d, _ in items)
    with_uv = any(d['uv'] is not None for d, _ in items)
    cos, tris, ns, uvs, base = [], [], [], [], 0
    for d, mat in items:
        m = np.array(mat, dtype=np.float64)
        co, tri, n, uv = d['co'], d['tri'], d['n'], d['uv']
        if with_n and n is None:
            corners = tri.reshape(-1)
            co, uv = co[corners], (uv[corners] if uv is not None else None)
            tri = np.arange(len(corners), dtype=np.int32).reshape(-1, 3)
            p = co.reshape(-1, 3, 3).astype(np.float64)
            fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
            fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
            n = np.repeat(fn, 3, axis=0)
        cos.append((co.astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32))
        if with_n:
            w = n.astype(np.float64) @ np.linalg.inv(m[:3, :3])
            w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)
            ns.append(w.astype(np.float32))
        if with_uv:
            uvs.append(uv if uv is not None else np.zeros((len(co), 2), dtype=np.float32))
        if np.linalg.det(m[:3, :3]) < 0:
            tri = tri[:, [0, 2, 1]]  # keep the winding outward, as Cycles does
        tris.append(tri + base)
        base += len(co)
    return {'co': np.concatenate(cos), 'tri': np.concatenate(tris),
            'n': np.concatenate(ns) if with_n else None,
            'uv': np.concatenate(uvs) if with_uv else None}


def split_corners(co, tri, loops, corner_vert, normals, uv):
    """Per-vertex normals and UVs from per-corner (loop) ones: a vertex
    whose corners all agree keeps its index; each other distinct (vertex,
    normal, UV) becomes a new vertex after the original ones. Works on the
    mesh's corners (4 a quad, not 6), in numpy without a loop over them.
    Returns (co, tri, n or None, uv or None)."""
    import numpy as np
    nv = len(co)
    corner = normals is not None and normals[0] == 'corner'
    vn = normals[1] if normals is not None and normals[0] == 'point' else None
    cols = ([normals[1]] if corner else []) + ([uv] if uv is not None else [])
    if not cols:
        return co, tri, vn, None
    attr = np.ascontiguousarray(np.concatenate(cols, axis=1) if len(cols) > 1 else cols[0],
                                dtype=np.float32)
    k = attr.shape[1]
    rep = np.zeros((nv, k), dtype=np.float32)
    if corner:
        rep[:, 2] = 1.0  # vertices no corner uses
    rep[corner_vert] = attr  # one corner's values per vertex
    same = (attr == rep[corner_vert]).all(axis=1)
    diff = np.flatnonzero(~same)
    if len(diff):
        keys = np.empty((len(diff), k + 1), dtype=np.uint32)
        keys[:, 0] = corner_vert[diff]
        keys[:, 1:] = attr[diff].view(np.uint32)
        rows = keys.view(np.dtype((np.void, 4 * (k + 1)))).ravel()
        _, first, inv = np.unique(rows, return_index=True, return_inverse=True)
        new_vert = corner_vert.copy()
        new_vert[diff] = nv + inv.reshape(-1)
        vmap = np.concatenate([np.arange(nv), keys[first, 0].astype(np.int64)])
        rep = np.concatenate([rep, attr[diff[first]]])
        co = co[vmap]
        if vn is not None:
            vn = vn[vmap]
        tri = new_vert[loops].astype(np.int32)
    n = rep[:, :3] if corner else vn
    return co, tri, n, (rep[:, -2:] if uv is not None else None)


def write_ply(path, co, tri, n=None, uv=None):
    """A binary little-endian PLY (vertex float x y z, then nx ny nz with
    normals, s t with UVs; face list uchar int vertex_indices) written
    atomically; raises ExportError."""
    import numpy as np
    props = ['x', 'y', 'z'] + (['nx', 'ny', 'nz'] if n is not None else []) + \
        (['s', 't'] if uv is not None else [])
    header = ('ply\nformat binary_little_endian 1.0\ncomment vdbphoton_export.py\n'
              f'element vertex {len(co)}\n' +
              ''.join(f'property float {p}\n' for p in props) +
              f'element face {len(tri)}\n'
              'property list uchar int vertex_indices\nend_header\n')
    cols = [co] + ([n] if n is not None else []) + ([uv] if uv is not None else [])
    verts = np.ascontiguousarray(np.concatenate(cols, axis=1) if len(cols) > 1 else co,
                                 dtype='<f4')
    faces = np.empty(len(tri), dtype=np.dtype([('n', 'u1'), ('v', '<i4', (3,))]))
    faces['n'] = 3
    faces['v'] = tri
    d = os.path.dirname(path)
    tmp = os.path.join(d, f'.{os.path.basename(path)}.{os.getpid()}.tmp')
    try:
        with open(tmp, 'wb') as f:
            f.write(header.encode('ascii'))
            f.write(verts.tobytes())
            f.write(faces.tobytes())
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise ExportError(f'cannot write {path}: {e.strerror or e}') from None
