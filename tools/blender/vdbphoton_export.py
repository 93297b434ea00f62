"""Export the current Blender scene as a vdbphoton scene file (TOML).

Usage (any of):

    blender -b FILE.blend -P tools/blender/vdbphoton_export.py -- OUT.toml \
        [--frames A-B] [--output 'renders/frame_{frame:04}.exr'] [--preview P.png | --no-preview]
        [--scene NAME] [--cache-temperature] [--fluid-velocity blender|physical]
    VENV/bin/python tools/blender/vdbphoton_export.py FILE.blend OUT.toml [same options]
    as an add-on: File > Export > vdbphoton scene (.toml)

VENV is a Python 3.11 venv with `pip install bpy==5.0.1`.

What is exported (docs/scene.md and the frame/camera keys of the pipeline
CLI):
  [render]   width/height = resolution x percentage; spp = Cycles samples;
             seed; max_bounces = min(Volume, Total bounces) + 1 (Cycles
             counts bounces after the first scattering, vdbphoton counts
             scattering events); frames = the scene's frame range (or
             --frames); output/preview = Blender's output path with '#'
             for the frame (or --output); exposure = the view exposure;
             motion_blur, shutter (frames), shutter_position and fps
             (fps / fps_base) when Motion Blur is on.
  [camera]   Blender's camera: matrix (matrix_world, scale removed),
             focal_length, sensor_width/height, sensor_fit, shift_x/y.
             Orthographic and panoramic cameras are refused.
  [[light]]  sun (Strength -> irradiance W/m^2, Angle), point (Power P W ->
             intensity P/(4 pi) W/sr), spot (the same; Spot Size ->
             cone_angle, Blend -> blend); colour x strength (x blackbody
             colour when "Temperature" is used, x 2^exposure, x the Volume
             factor). Area lights and soft (radius > 0) lights are warned
             about.
  [environment]  a World whose Background (or Emission) has a constant
             Color (x Strength), or an Environment Texture (image file,
             Strength, Z rotation of a Mapping node). Anything else (sky
             texture, other nodes) is warned about, naming the world and
             node.
  [[volume]] every Volume object (its VDB file, absolute; an image
             sequence becomes a '#' pattern) and every gas fluid domain
             (its cache <cache_directory>/data/fluid_data_####.vdb, placed
             as Blender renders it, with bounds = the domain box). The
             object's Principled Volume (or Volume Scatter + Absorption)
             material becomes [volume.material], every key written; a
             Volume Scatter node's Phase (Henyey-Greenstein, Fournier-Forand,
             Draine, Rayleigh, Mie) its phase table, values outside
             vdbphoton's ranges clamped with a warning. What a material
             needs that vdbphoton cannot take is one warning naming object,
             material, the unsupported node and the socket it drives, and
             the nearest value is written (the attribute that node reads,
             or the socket's own value): no material stops the scene. As
             Cycles renders them (docs/from_blender.md, "Cycles'
             semantics"): a Volume object without a material is the
             default Principled Volume; an Attribute node naming a grid the
             file lacks reads 0. A
             Volume object with Space = Object (Blender's default) has its
             densities and emission scaled by 1 / |M (1,1,1)/sqrt 3|, as
             Cycles does. A domain's `temperature` attribute is made by
             Blender from the flame grid (ignition + flame x (max_temp -
             ignition) where flame > 0.01, else 0; 0 everywhere when the
             domain has no fire): a domain with fire (a Fire or Fire + Smoke
             flow, or a 'flame' grid in its cache) gets temperature_grid =
             "flame" and temperature_from_flame = [Flame Ignition, Maximum
             Temperature], which vdbphoton maps the same way;
             --cache-temperature uses the cache's `temperature` grid (the
             heat x 2) instead. A sequence or cache whose file number is not
             the frame gets frame_offset (vdbphoton reads file frame +
             frame_offset).
  [[mesh]]   every instance Blender renders as a surface (meshes with
             their modifiers, collection, Geometry Nodes and particle
             instances, linked duplicates; curves, surfaces, metaballs and
             text as the mesh Blender evaluates them into), from the render
             depsgraph's object_instances at the current frame: `file` (a
             binary PLY in '<scene stem>_meshes/' beside the scene file,
             one per distinct mesh, object space), `name`, `transform`
             (matrix_world), `holdout`, `shadow_catcher` and `visibility`
             (the ray types that are off) as Cycles takes them (see
             mesh_instances()). An animated mesh in a sequence is warned
             about (exported as at the current frame). The PLY holds the
             normals Blender shades with (nx ny nz; none when every face
             is flat) and the active render UV map (s t), vertices split
             where their corners differ; a mesh with several material slots
             becomes one PLY and one [[mesh]] per slot its faces use.
  [mesh.material]  the slot's material as Cycles shades it
             (SurfaceReader): the Surface of the Material Output active for
             Cycles followed (through reroutes and node groups) to a
             Principled BSDF (type "principled": base_color or
             base_color_texture, roughness, metallic, ior,
             specular_ior_level, specular_tint, emission_color,
             emission_strength), a Diffuse BSDF ("diffuse": color or
             color_texture, roughness) or an Emission ("emission": color,
             strength). An Image Texture on Base Color or a Diffuse BSDF's
             Color, through the UV map (an optional UV Map node, Texture
             Coordinate UV, identity Mapping), becomes { file, colorspace }:
             the file's absolute path; a packed image written into
             '<stem>_meshes/' (other formats than PNG, JPEG, EXR converted
             there); colorspace "srgb" or "linear". Anything else (other
             nodes into a socket, transmission, coat, sheen, subsurface, a
             normal map or bump, Mix and Add Shaders, other shaders, missing
             or generated images) is one warning naming object, material,
             node and socket, with the nearest supported shading written.
             No material: no table (Cycles' default surface).
  [render] film_transparent = Film > Transparent (written when on).

Warnings go to stderr as `vdbphoton_export: warning: ...`, each naming the
object, material and node concerned. Fatal problems (no camera, nothing
to export, output not writable) print one line `vdbphoton_export: error:
...` and exit with status 1 (2 for a bad command line); so does any
unexpected exception (never a traceback; in Blender, one error report).

Fluid domain placement (verified against Cycles 5.0.1 and 3.4.1 renders of
the shared Blender cache, tools/blender/README.md): Blender sets p0 = the
minimum of the domain mesh's local bounding box, cell = local size /
resolution per axis (the largest axis of size x object scale gets the
domain's Resolution Divisions, the others int(size*scale + 0.5), at least
4), and renders cache voxel i at local p0 + (i + 0.5) * cell. The cache's
own transform F (index -> file space, a uniform scale) is read from the
file, so the exported transform is

    matrix_world . Translate(p0 + cell/2) . Scale(cell) . F^-1
"""

bl_info = {
    "name": "vdbphoton",
    "author": "vdbphoton",
    "version": (1, 2, 0),
    "blender": (3, 4, 0),
    "location": "Render Properties > Render Engine > vdbphoton; "
                "File > Export > vdbphoton scene (.toml)",
    "description": "Render OpenVDB volumes and smoke domains with vdbphoton (a render "
                   "engine), or export them as a vdbphoton scene file",
    "category": "Render",
}

import math
import os
import re
import struct
import sys
import time

import bpy
from mathutils import Matrix, Vector

PREFIX = 'vdbphoton_export'

# Blender's default attribute names of a fluid domain (Cycles' standard
# volume attributes) -> the grids of a Mantaflow OpenVDB cache and the
# factor between them. Measured on the shared cache (Blender 3.4.1 bake, read
# by Blender 3.4.1 and 5.0.1): the domain's `heat` attribute is the cache's
# `temperature` grid / 2 exactly; `density` and `flame` are the grids as
# stored. `temperature` is special: Blender derives it from the flame
# (flame_ignition + flame * (flame_max_temp - flame_ignition) where flame >
# 0.01, else 0), see domain_attribute().
DOMAIN_GRIDS = {'density': ('density', 1.0), 'flame': ('flame', 1.0),
                'heat': ('temperature', 0.5)}


class ExportError(Exception):
    pass


# An argument not given (where None is a value).
UNSET = object()


def f32(x):
    return struct.unpack('f', struct.pack('f', x))[0]


# ------------------------------------------------------------------ TOML

def toml_str(s):
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == '\\':
            out.append('\\\\')
        elif ord(ch) < 0x20 or ord(ch) == 0x7f:
            out.append('\\u%04x' % ord(ch))
        else:
            out.append(ch)
    out.append('"')
    return ''.join(out)


def toml_num(x):
    if isinstance(x, bool):
        return 'true' if x else 'false'
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if not math.isfinite(x):
        raise ExportError(f'cannot write the non-finite number {x}')
    s = repr(x + 0.0)
    if '.' not in s and 'e' not in s:
        s += '.0'
    return s


def toml_value(v):
    if isinstance(v, str):
        return toml_str(v)
    if isinstance(v, (list, tuple)):
        return '[' + ', '.join(toml_value(x) for x in v) + ']'
    if isinstance(v, dict):
        return '{ ' + ', '.join(f'{k} = {toml_value(x)}' for k, x in v.items()) + ' }'
    return toml_num(v)


def to_toml(doc):
    """doc: {'header': [comment lines], 'render': {}, 'camera': {},
    'light': [{}], 'environment': {} | None, 'volume': [{'_comment': str,
    ..., 'material': {}}], 'mesh': [{'_comment': str, 'file': ..., ...}]}"""
    lines = [f'# {c}' for c in doc['header']]

    def table(name, t):
        lines.append('')
        if t.get('_comment'):
            lines.append(f"# {t['_comment']}")
        lines.append(f'[{name}]')
        for k, v in t.items():
            if not k.startswith('_'):
                lines.append(f'{k} = {toml_value(v)}')

    table('render', doc['render'])
    table('camera', doc['camera'])
    for L in doc['light']:
        lines.append('')
        if L.get('_comment'):
            lines.append(f"# {L['_comment']}")
        lines.append('[[light]]')
        for k, v in L.items():
            if not k.startswith('_'):
                lines.append(f'{k} = {toml_value(v)}')
    if doc['environment'] is not None:
        table('environment', doc['environment'])
    for v in doc['volume']:
        lines.append('')
        for c in v.get('_comment', []):
            lines.append(f'# {c}')
        lines.append('[[volume]]')
        for k, x in v.items():
            if k.startswith('_') or k == 'material':
                continue
            lines.append(f'{k} = {toml_value(x)}')
        lines.append('[volume.material]')
        for k, x in v['material'].items():
            lines.append(f'{k} = {toml_value(x)}')
    for m in doc.get('mesh', []):
        lines.append('')
        if m.get('_comment'):
            lines.append(f"# {m['_comment']}")
        lines.append('[[mesh]]')
        for k, x in m.items():
            if not k.startswith('_') and k != 'material':
                lines.append(f'{k} = {toml_value(x)}')
        if m.get('material') is not None:
            lines.append('[mesh.material]')
            for k, x in m['material'].items():
                lines.append(f'{k} = {toml_value(x)}')
    return '\n'.join(lines) + '\n'


# ------------------------------------------------------------- utilities

def rgb3(c):
    return [float(c[0]), float(c[1]), float(c[2])]


def g7(x):
    """A float32 value with the digits it has (7 significant)."""
    return float('%.7g' % float(x)) + 0.0


def rounded(v, digits=7):
    fmt = '%%.%dg' % digits
    return [float(fmt % float(x)) + 0.0 for x in v]


def matrix_rows(m, digits=9):
    fmt = '%%.%dg' % digits
    rows = [[float(fmt % float(m[i][j])) + 0.0 for j in range(4)] for i in range(4)]
    rows[3] = [0.0, 0.0, 0.0, 1.0]
    return rows


def frame_range_text(start, end, step):
    if start == end:
        return str(start)
    s = f'{start}-{end}'
    return s + (f':{step}' if step != 1 else '')


FRAMES_RE = re.compile(r'^\s*-?\d+(\s*-\s*-?\d+(\s*:\s*\d+)?)?(\s*,\s*-?\d+(\s*-\s*-?\d+(\s*:\s*\d+)?)?)*\s*$')


def expand_frames(text):
    out = []
    for part in text.split(','):
        part = part.strip()
        step = 1
        if ':' in part:
            part, s = part.split(':')
            step = max(1, int(s))
        m = re.match(r'^(-?\d+)\s*(?:-\s*(-?\d+))?$', part.strip())
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        out.extend(range(a, b + 1, step))
    return out


def compress_frames(frames):
    frames = sorted(set(frames))
    runs, i = [], 0
    while i < len(frames):
        j = i
        while j + 1 < len(frames) and frames[j + 1] == frames[j] + 1:
            j += 1
        runs.append(str(frames[i]) if i == j else f'{frames[i]}-{frames[j]}')
        i = j + 1
    return ','.join(runs)


def sequence_pattern(path):
    """Blender's BLI_path_frame_get: the last run of digits in the file name
    (before its extension). Returns (pattern with '#' * digits, number,
    digits) or None."""
    d, name = os.path.split(path)
    stem, ext = os.path.splitext(name)
    m = None
    for m in re.finditer(r'\d+', stem):
        pass
    if m is None:
        return None
    pat = stem[:m.start()] + '#' * len(m.group()) + stem[m.end():] + ext
    return os.path.join(d, pat), int(m.group()), len(m.group())


def pattern_path(pattern, frame):
    def sub(m):
        return str(frame).zfill(len(m.group()))
    d, name = os.path.split(pattern)
    return os.path.join(d, re.sub(r'#+', sub, name))


# ---------------------------------------------------------------- exporter

class Exporter:
    def __init__(self, scene, view_layer=None, frames=None, output=None, preview=None,
                 no_preview=False, cache_temperature=False, warn=None, blend_path=None,
                 fluid_velocity='blender', depsgraph=None, scene_path=None):
        self.scene = scene
        self.view_layer = view_layer or scene.view_layers[0]
        # The render depsgraph (the engine's), or None: the exporter makes
        # one when there are meshes (render_depsgraph()).
        self.depsgraph = depsgraph
        # Where the scene file goes: its meshes go into '<stem>_meshes/'
        # beside it (None: meshes are not written, as for a dry run).
        self.scene_path = scene_path
        self.meshes = {}
        self.texture_paths = {}
        self.texture_files = {}
        self.packed_written = {}
        self.mesh_parts = {}
        self.instances = 0
        self.uv_told = set()
        self.surfaces = SurfaceReader(self)
        self.checked = set()
        self.frames_arg = frames
        self.output_arg = output
        self.preview_arg = preview
        self.no_preview = no_preview
        self.cache_temperature = cache_temperature
        if fluid_velocity not in ('blender', 'physical'):
            raise ExportError(f"fluid velocity {fluid_velocity!r}: expected 'blender' or "
                              "'physical'")
        self.fluid_velocity = fluid_velocity
        self.warnings = []
        self.notes = []
        self._warn_cb = warn
        self.blend_path = blend_path or bpy.data.filepath

    def warn(self, msg):
        self.warnings.append(msg)
        if self._warn_cb:
            self._warn_cb('warning', msg)

    def note(self, msg):
        self.notes.append(msg)
        if self._warn_cb:
            self._warn_cb('note', msg)

    # -- visibility

    def render_objects(self):
        """Objects Blender renders in this view layer (excluded or
        render-disabled collections and hide_render objects left out)."""
        visible = set()

        def walk(lc, parent_ok):
            ok = parent_ok and not lc.exclude and not lc.collection.hide_render
            if ok:
                for o in lc.collection.objects:
                    visible.add(o.name_full)
            for c in lc.children:
                walk(c, ok)

        walk(self.view_layer.layer_collection, True)
        out = []
        for o in self.scene.objects:
            if o.name_full in visible and not o.hide_render:
                out.append(o)
        return out

    # -- render

    def export_render(self):
        sc = self.scene
        r = sc.render
        width = r.resolution_x * r.resolution_percentage // 100
        height = r.resolution_y * r.resolution_percentage // 100
        if width < 1 or height < 1:
            raise ExportError(f'render size {width} x {height} is empty')
        out = {'width': width, 'height': height}
        cy = getattr(sc, 'cycles', None)
        if r.engine != 'CYCLES':
            self.note(f"scene '{sc.name}' renders with {r.engine}; samples and bounces are "
                      "taken from its Cycles settings")
        if cy is not None:
            out['spp'] = max(1, int(cy.samples))
            out['seed'] = max(0, int(cy.seed))
            vb = int(cy.volume_bounces)
            tb = int(cy.max_bounces)
            out['max_bounces'] = min(vb, tb) + 1
        if r.use_border:
            self.warn(f"scene '{sc.name}': render region (border) is not exported; "
                      "the whole frame is rendered")
        if r.pixel_aspect_x != r.pixel_aspect_y:
            self.warn(f"scene '{sc.name}': pixel aspect {r.pixel_aspect_x}:{r.pixel_aspect_y} "
                      "is not supported (square pixels are rendered)")
        if r.use_motion_blur:
            out['motion_blur'] = True
            out['shutter'] = g7(r.motion_blur_shutter)
            out['shutter_position'] = r.motion_blur_position.lower()
            out['fps'] = g7(r.fps / r.fps_base)
            if r.motion_blur_position == 'END':
                self.warn(f"scene '{sc.name}': motion blur Position End: Blender 5.0.1 "
                          "blurs over the shutter's length after the frame instead of before "
                          "it; vdbphoton blurs over the shutter ending at the frame")
            if getattr(cy, 'rolling_shutter_type', 'NONE') != 'NONE':
                self.warn(f"scene '{sc.name}': the rolling shutter is not exported (every "
                          "row is blurred over the same shutter)")
            curve = r.motion_blur_shutter_curve
            pts = [tuple(round(c, 6) for c in p.location) for p in curve.curves[0].points]
            if len(pts) > 2 or any(p[1] != 1.0 for p in pts):
                self.warn(f"scene '{sc.name}': the motion blur Shutter Curve is not exported "
                          "(vdbphoton's shutter is open fully over its whole length, "
                          "Blender's default curve)")
        if self.frames_arg:
            if not FRAMES_RE.match(self.frames_arg):
                raise ExportError(f"--frames {self.frames_arg!r}: expected a list like 1-40 "
                                  "or 1-3,5,7-20:2")
            frames_text = self.frames_arg.replace(' ', '')
        else:
            frames_text = frame_range_text(sc.frame_start, sc.frame_end, sc.frame_step)
        self.frames = expand_frames(frames_text)
        if not self.frames:
            raise ExportError(f'the frame list {frames_text!r} is empty')
        out['frames'] = frames_text
        if self.output_arg:
            output = self.output_arg
        else:
            output = blender_output_pattern(r.filepath, self.blend_path)
        if not output.endswith('.exr'):
            output = os.path.splitext(output)[0] + '.exr' if output.endswith('.png') else output + '.exr'
        out['output'] = output
        if not self.no_preview:
            out['preview'] = self.preview_arg or (output[:-4] + '.png')
        if r.film_transparent:
            # Film > Transparent: the world seen directly is in neither
            # colour nor alpha (premultiplied RGBA).
            out['film_transparent'] = True
        vs = sc.view_settings
        if vs.exposure != 0.0:
            out['exposure'] = g7(vs.exposure)
        if vs.view_transform not in ('Standard', 'Raw'):
            self.note(f"view transform '{vs.view_transform}': the PNG preview uses vdbphoton's "
                      f"--view (e.g. --view {vs.view_transform.lower()}); the EXR is linear")
        return out

    # -- camera

    def export_camera(self):
        sc = self.scene
        co = sc.camera
        if co is None:
            raise ExportError(f"scene '{sc.name}' has no active camera")
        if co.type != 'CAMERA':
            raise ExportError(f"the active camera '{co.name}' is not a camera object")
        cam = co.data
        if cam.type == 'ORTHO':
            raise ExportError(f"camera '{co.name}' is orthographic; vdbphoton renders only "
                              "perspective (pinhole) cameras")
        if cam.type == 'PANO':
            raise ExportError(f"camera '{co.name}' is panoramic; vdbphoton renders only "
                              "perspective (pinhole) cameras")
        if cam.dof.use_dof:
            self.warn(f"camera '{co.name}': depth of field is not supported (rendered sharp)")
        mw = co.matrix_world
        loc, rot, _scale = mw.decompose()
        m = Matrix.Translation(loc) @ rot.to_matrix().to_4x4()
        out = {'_comment': f"Blender camera '{co.name}'",
               'matrix': matrix_rows(m, 7),
               'focal_length': g7(cam.lens),
               'sensor_width': g7(cam.sensor_width),
               'sensor_height': g7(cam.sensor_height),
               'sensor_fit': cam.sensor_fit.lower()}
        if cam.shift_x != 0.0:
            out['shift_x'] = g7(cam.shift_x)
        if cam.shift_y != 0.0:
            out['shift_y'] = g7(cam.shift_y)
        return out

    # -- lights

    def light_colour(self, o):
        L = o.data
        col = Vector(rgb3(L.color))
        if getattr(L, 'use_temperature', False):
            col = Vector([col[i] * L.temperature_color[i] for i in range(3)])
        k = 2.0 ** float(getattr(L, 'exposure', 0.0))
        k *= float(getattr(L, 'volume_factor', 1.0))
        if getattr(L, 'volume_factor', 1.0) != 1.0:
            self.note(f"light '{o.name}': its Volume factor {L.volume_factor} is applied")
        if getattr(L, 'use_nodes', False) and L.node_tree is not None:
            strength, ncol = self.light_nodes(o)
            k *= strength
            col = Vector([col[i] * ncol[i] for i in range(3)])
        return col * k

    def light_nodes(self, o):
        nt = o.data.node_tree
        outs = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputLight' and n.is_active_output]
        if not outs or not outs[0].inputs['Surface'].is_linked:
            return 1.0, (1.0, 1.0, 1.0)
        n = follow(outs[0].inputs['Surface'])
        if n.bl_idname != 'ShaderNodeEmission' or n.inputs['Strength'].is_linked \
                or n.inputs['Color'].is_linked:
            self.warn(f"light '{o.name}': light node '{n.name}' is not supported "
                      "(only an Emission node with constant inputs); its nodes are ignored")
            return 1.0, (1.0, 1.0, 1.0)
        return float(n.inputs['Strength'].default_value), rgb3(n.inputs['Color'].default_value)

    def export_lights(self, objects):
        lights = []
        for o in objects:
            if o.type != 'LIGHT':
                continue
            L = o.data
            mw = o.matrix_world
            col = self.light_colour(o)
            if L.type == 'AREA':
                self.warn(f"light '{o.name}' is an area light, which vdbphoton does not "
                          "support; it is not exported")
                continue
            if not getattr(L, 'use_shadow', True):
                self.warn(f"light '{o.name}': 'Cast Shadow' off is not supported "
                          "(vdbphoton's lights always cast shadows)")
            if L.type == 'SUN':
                d = (mw.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()
                lights.append({'_comment': f"Blender sun '{o.name}'", 'type': 'sun',
                               'direction': rounded(d),
                               'irradiance': rounded(col * float(L.energy)),
                               'angle': g7(math.degrees(L.angle))})
                continue
            if L.type not in ('POINT', 'SPOT'):
                self.warn(f"light '{o.name}' of type {L.type} is not supported; not exported")
                continue
            if L.shadow_soft_size > 0.0:
                self.warn(f"light '{o.name}': radius {L.shadow_soft_size:g} m (soft light) is "
                          "rendered as a point light by vdbphoton")
            pos = mw.to_translation()
            t = {'_comment': f"Blender {L.type.lower()} light '{o.name}' ({L.energy:g} W)",
                 'type': L.type.lower(), 'position': rounded(pos),
                 'intensity': rounded(col * (float(L.energy) / (4.0 * math.pi)))}
            if L.type == 'SPOT':
                d = (mw.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
                t['direction'] = rounded(d)
                t['cone_angle'] = g7(min(180.0, math.degrees(L.spot_size)))
                t['blend'] = g7(L.spot_blend)
                s = mw.to_scale()
                if abs(s.x - s.y) > 1e-6 * max(abs(s.x), abs(s.y)):
                    self.warn(f"spot light '{o.name}': non-uniform scale makes Blender's cone "
                              "elliptic; vdbphoton's is round")
            lights.append(t)
        return lights

    # -- world

    def export_world(self):
        w = self.scene.world
        if w is None:
            return None
        nt = w.node_tree if uses_nodes(w) else None
        if nt is None:
            c = rgb3(w.color)
            return {'_comment': f"Blender world '{w.name}' (colour)", 'radiance': rounded(c)}
        outs = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputWorld']
        act = [n for n in outs if n.is_active_output and n.target in ('ALL', 'CYCLES')] or \
              [n for n in outs if n.is_active_output] or outs
        for n in nt.nodes:
            if n.bl_idname == 'ShaderNodeTexSky':
                self.warn(f"world '{w.name}': node '{n.name}' (Sky Texture) is not supported")
        if not act:
            return None
        out = act[0]
        if out.inputs['Volume'].is_linked:
            self.warn(f"world '{w.name}': node '{follow(out.inputs['Volume']).name}' (world "
                      "volume) is not supported")
        if not out.inputs['Surface'].is_linked:
            return None
        bg = follow(out.inputs['Surface'])
        if bg.bl_idname not in ('ShaderNodeBackground', 'ShaderNodeEmission'):
            if bg.bl_idname == 'ShaderNodeTexSky':
                return None
            self.warn(f"world '{w.name}': node '{bg.name}' ({bg.bl_label}) is not supported; "
                      "the environment is not exported (black)")
            return None
        st = bg.inputs['Strength']
        if st.is_linked:
            self.warn(f"world '{w.name}': node '{follow(st).name}' drives the Strength of "
                      f"'{bg.name}'; not supported (the environment is not exported)")
            return None
        strength = float(st.default_value)
        ci = bg.inputs['Color']
        if not ci.is_linked:
            c = [x * strength for x in rgb3(ci.default_value)]
            return {'_comment': f"Blender world '{w.name}' (constant colour x strength)",
                    'radiance': rounded(c)}
        src = follow(ci)
        if src.bl_idname == 'ShaderNodeRGB':
            c = [x * strength for x in rgb3(src.outputs[0].default_value)]
            return {'_comment': f"Blender world '{w.name}' (constant colour x strength)",
                    'radiance': rounded(c)}
        if src.bl_idname != 'ShaderNodeTexEnvironment':
            if src.bl_idname == 'ShaderNodeTexSky':
                return None
            self.warn(f"world '{w.name}': node '{src.name}' ({src.bl_label}) feeding the "
                      "background colour is not supported; the environment is not exported")
            return None
        img = src.image
        if img is None:
            self.warn(f"world '{w.name}': node '{src.name}' has no image; not exported")
            return None
        if img.packed_file is not None:
            self.warn(f"world '{w.name}': image '{img.name}' of node '{src.name}' is packed "
                      "in the .blend; unpack it to a file to export it")
            return None
        if src.projection != 'EQUIRECTANGULAR':
            self.warn(f"world '{w.name}': node '{src.name}' uses {src.projection} projection; "
                      "only equirectangular maps are supported")
        path = os.path.normpath(bpy.path.abspath(img.filepath, library=img.library))
        env = {'_comment': f"Blender world '{w.name}' (environment texture '{img.name}')",
               'map': path, 'strength': g7(strength)}
        rot = 0.0
        vi = src.inputs['Vector']
        if vi.is_linked:
            mp = follow(vi)
            if mp.bl_idname == 'ShaderNodeMapping':
                rot = self.mapping_rotation(w, mp)
            elif mp.bl_idname != 'ShaderNodeTexCoord':
                self.warn(f"world '{w.name}': node '{mp.name}' ({mp.bl_label}) feeding the "
                          f"vector of '{src.name}' is not supported (ignored)")
        if rot is not None and rot != 0.0:
            env['rotate_z'] = g7(rot)
        return env

    def mapping_rotation(self, w, mp):
        """vdbphoton's rotate_z for a Mapping node: it looks the map up at
        R(-rotate_z) w (src/light.rs); a POINT/VECTOR mapping turns the
        vector by R(rz), a TEXTURE mapping by R(-rz)."""
        ins = mp.inputs
        for name in ('Location', 'Rotation', 'Scale'):
            if name in ins and ins[name].is_linked:
                self.warn(f"world '{w.name}': the {name} of Mapping node '{mp.name}' is linked; "
                          "not supported (no rotation exported)")
                return None
        rx, ry, rz = ins['Rotation'].default_value
        sx, sy, sz = ins['Scale'].default_value
        loc = ins['Location'].default_value if 'Location' in ins else (0, 0, 0)
        if abs(rx) > 1e-7 or abs(ry) > 1e-7:
            self.warn(f"world '{w.name}': Mapping node '{mp.name}' rotates about X or Y; only "
                      "the Z rotation is exported")
        if not (abs(sx - sy) < 1e-6 and abs(sy - sz) < 1e-6) or \
                (mp.vector_type == 'POINT' and max(abs(x) for x in loc) > 1e-7):
            self.warn(f"world '{w.name}': Mapping node '{mp.name}' has a location or "
                      "non-uniform scale; not supported (ignored)")
        if mp.vector_type in ('POINT', 'VECTOR'):
            return -math.degrees(rz)
        if mp.vector_type == 'TEXTURE':
            return math.degrees(rz)
        self.warn(f"world '{w.name}': Mapping node '{mp.name}' of type {mp.vector_type} is "
                  "not supported")
        return None

    # -- volumes

    def grid_info(self, path):
        """(grid names, {name: data_type}, index->file matrix) of a VDB file,
        read by Blender, or None."""
        if not os.path.isfile(path):
            return None
        vol = bpy.data.volumes.new('.vdbphoton_export_probe')
        try:
            vol.filepath = path
            try:
                ok = vol.grids.load()
            except Exception:  # noqa: BLE001
                ok = False
            if not ok or len(vol.grids) == 0:
                return None
            names = [g.name for g in vol.grids]
            types = {g.name: g.data_type for g in vol.grids}
            mats = {g.name: Matrix(g.matrix_object) for g in vol.grids}
            return names, types, mats
        finally:
            bpy.data.volumes.remove(vol)

    def export_volume_object(self, o):
        vol = o.data
        what = f"volume object '{o.name}'"
        if vol.packed_file is not None:
            self.warn(f"{what}: its VDB file is packed in the .blend; unpack it to export it")
            return None
        path = os.path.normpath(bpy.path.abspath(vol.filepath, library=vol.library))
        comment = [f"Blender {what}, file {vol.filepath}"]
        entry = {'file': None}
        frame_files = {}
        if vol.is_sequence:
            sp = sequence_pattern(path)
            if sp is None:
                self.warn(f"{what}: 'Sequence' is on but the file name {os.path.basename(path)} "
                          "has no frame number; exported as a single file")
                file_value = path
                probe = path
            else:
                pattern = sp[0]
                # BKE_volume_time (CLIP/EXTEND/REPEAT/PING_PONG), then + offset.
                k = 1 - vol.frame_start + vol.frame_offset
                for f in self.frames:
                    n = volume_sequence_frame(vol, f)
                    frame_files[f] = None if n is None else pattern_path(pattern, n)
                irregular = [f for f in self.frames
                             if frame_files[f] is not None and frame_files[f] != pattern_path(pattern, f + k)]
                outside = [f for f in self.frames if frame_files[f] is None]
                if irregular:
                    self.warn(f"{what}: sequence mode {vol.sequence_mode} repeats or holds files "
                              f"at frames {compress_frames(irregular)}; vdbphoton reads file "
                              "frame + offset there")
                if outside:
                    self.warn(f"{what}: frames {compress_frames(outside)} are outside the "
                              "sequence (Blender shows no volume there); vdbphoton will fail "
                              "those frames")
                file_value = pattern
                if k != 0:
                    # vdbphoton: frame f reads file frame f + frame_offset.
                    entry['frame_offset'] = k
                    comment.append(f"sequence Start Frame {vol.frame_start}, Offset "
                                   f"{vol.frame_offset}: file = frame {k:+d} (frame_offset)")
                existing = [p for p in frame_files.values() if p and os.path.isfile(p)]
                missing = [f for f, p in frame_files.items() if p and not os.path.isfile(p)]
                if missing:
                    self.warn(f"{what}: no file for frames {compress_frames(missing)} "
                              f"({os.path.basename(pattern)})")
                probe = existing[0] if existing else path
        else:
            file_value = path
            probe = path
        info = self.grid_info(probe)
        if info is None:
            self.warn(f"{what}: cannot read grids from {probe}; grid names are not checked")
            names, types = None, {}
        else:
            names, types, _ = info
        entry['file'] = file_value
        mat = self.object_material(o)
        resolve = lambda attr: volume_attribute(attr, names)  # noqa: E731
        m = self.export_material(o, mat, resolve, types, comment, names)
        if m is None:
            return None
        entry.update(m['grids'])
        mw = o.matrix_world
        entry['transform'] = {'matrix': matrix_rows(mw, 7)}
        if vol.render.space == 'OBJECT':
            # Cycles' object_volume_density(): with Space = Object the
            # densities and emission are per object-space length, scaled by
            # 1 / |M (1,1,1)/sqrt 3| in every direction.
            f = 1.0 / (mw.to_3x3() @ Vector((1.0, 1.0, 1.0)).normalized()).length
            if abs(f - 1.0) > 1e-6:
                scale_material(m['material'], f)
                comment.append(f"volume Space = Object: densities and emission x {f:.7g} "
                               "(Blender's 1 / |M (1,1,1)/sqrt 3|)")
        entry['material'] = m['material']
        self.volume_velocity(vol, names, entry, comment, what)
        entry['_comment'] = comment
        for mod in o.modifiers:
            if mod.show_render:
                self.warn(f"{what}: modifier '{mod.name}' ({mod.type}) is not applied; the "
                          "file is rendered as it is")
        return entry

    def volume_velocity(self, vol, names, entry, comment, what):
        """A Volume object's velocity settings (Blender's Volume data,
        Velocity panel): the grid when not the default, scale and unit."""
        grid = vol.velocity_grid
        if grid and grid != 'velocity':
            if names is not None and grid not in names and not all(
                    f'{grid}{c}' in names for c in ('.x', '.y', '.z')):
                self.warn(f"{what}: its Velocity Grid '{grid}' is not in the file; no "
                          "motion blur for it")
            else:
                entry['velocity_grid'] = grid
        if vol.velocity_scale != 1.0:
            entry['velocity_scale'] = g7(vol.velocity_scale)
        if vol.velocity_unit == 'FRAME':
            entry['velocity_unit'] = 'frame'
            if self.scene.render.use_motion_blur and self.scene.render.motion_blur_shutter != 1.0:
                self.warn(f"{what}: velocity unit Frame: Blender 5.0.1 ignores the shutter "
                          "for velocities per frame (its blur is always one frame's motion); "
                          "vdbphoton blurs over the shutter")

    def export_domain(self, o, mod):
        ds = mod.domain_settings
        what = f"fluid domain '{o.name}'"
        if ds.cache_data_format != 'OPENVDB':
            self.warn(f"{what}: its cache format is {ds.cache_data_format}; only OpenVDB caches "
                      "can be rendered (set Cache > Format Volumes to OpenVDB and bake again)")
            return None
        cache = os.path.normpath(bpy.path.abspath(ds.cache_directory, library=o.library))
        pattern = os.path.join(cache, 'data', 'fluid_data_####.vdb')
        comment = [f"Blender {what}, cache {ds.cache_directory} (Mantaflow, OpenVDB)"]
        entry = {'file': pattern}
        offset = int(ds.cache_frame_offset)
        if offset != 0:
            # Blender reads cache frame (scene frame - offset); vdbphoton
            # frame f reads file frame f + frame_offset.
            entry['frame_offset'] = -offset
            comment.append(f"cache Offset {offset}: file = frame {-offset:+d} (frame_offset)")
        if ds.use_adaptive_domain:
            self.warn(f"{what}: Adaptive Domain is on; the cache is placed as a whole domain, "
                      "which is wrong where the adaptive region moved (turn it off and bake again)")
        if ds.use_noise:
            self.warn(f"{what}: the noise (high resolution) cache is not exported; vdbphoton "
                      "renders the base resolution")
        idx = list(o.modifiers).index(mod)
        before = [m.name for m in o.modifiers[:idx] if m.show_render]
        if before:
            self.warn(f"{what}: modifiers before the fluid modifier ({', '.join(before)}) are "
                      "ignored in the domain's placement")
        outside = [f for f in self.frames
                   if not (ds.cache_frame_start <= f <= ds.cache_frame_end)]
        if outside:
            self.warn(f"{what}: frames {compress_frames(outside)} are outside the cache range "
                      f"{ds.cache_frame_start}-{ds.cache_frame_end} (Blender shows no smoke "
                      "there); vdbphoton will fail those frames")
        files = {f: os.path.join(cache, 'data', f'fluid_data_{f - offset:04d}.vdb')
                 for f in self.frames}
        missing = [f for f, p in files.items() if not os.path.isfile(p) and f not in outside]
        if missing:
            self.warn(f"{what}: the cache has no file for frames {compress_frames(missing)} "
                      f"(in {os.path.join(cache, 'data')}); bake them first")
        existing = [p for p in files.values() if os.path.isfile(p)]
        info = self.grid_info(existing[0]) if existing else None
        names, types, fmat = (None, {}, None) if info is None else info
        place = domain_placement(o, ds)
        F = None
        if fmat:
            F = fmat.get('density') or next(iter(fmat.values()))
            vs = F.to_3x3().to_scale()
            if max(abs(vs[i] - place['dx']) for i in range(3)) > 1e-4 * place['dx'] or \
                    F.to_translation().length > 1e-6 * place['dx']:
                self.warn(f"{what}: the cache's voxel size {vs[0]:.6g} does not match the "
                          f"domain's settings (expected {place['dx']:.6g}: resolution "
                          f"{tuple(place['res'])}); was it baked with other settings?")
        else:
            F = Matrix.Diagonal((place['dx'],) * 3).to_4x4()
            self.warn(f"{what}: no cache file to read in the frame range; its transform is "
                      "computed from the domain settings alone")
        T = o.matrix_world @ place['index_to_local'] @ F.inverted()
        mat = self.object_material(o)
        fire = self.domain_fire(o, ds, names)
        if fire:
            comment.append(f"fire: {fire}; flame ignition {ds.flame_ignition:g}, maximum "
                           f"temperature {ds.flame_max_temp:g}")
        resolve = lambda attr: self.domain_attribute(attr, names, what, ds, fire)  # noqa: E731
        m = self.export_material(o, mat, resolve, types, comment, names, domain=True)
        if m is None:
            return None
        entry.update(m['grids'])
        res = place['res']
        lo = F @ Vector((-0.5, -0.5, -0.5))
        hi = F @ Vector((res[0] - 0.5, res[1] - 0.5, res[2] - 0.5))
        entry['bounds'] = [rounded([min(lo[i], hi[i]) for i in range(3)], 9),
                           rounded([max(lo[i], hi[i]) for i in range(3)], 9)]
        entry['transform'] = {'matrix': matrix_rows(T)}
        entry['material'] = m['material']
        if self.fluid_velocity == 'physical':
            # Mantaflow's cells per time unit, a frame being 0.1 x 25 / fps x
            # time_scale time units (Blender's frame_length): in file units
            # per second, 2.5 x time_scale x voxel.
            k = 2.5 * ds.time_scale * F.to_3x3().to_scale()[0] * ds.velocity_scale
            entry['velocity_scale'] = g7(k)
            comment.append(f"velocity: Mantaflow's cells per time unit as units per second "
                           f"(2.5 x time scale {ds.time_scale:g} x voxel x Velocity Scale "
                           f"{ds.velocity_scale:g})")
        else:
            # Cycles reads the raw velocity as units per second in the
            # domain object's space: per axis, voxel / local cell.
            dx = F.to_3x3().to_scale()[0]
            k = [dx / place['cell'][i] * ds.velocity_scale for i in range(3)]
            entry['velocity_scale'] = rounded(k)
            comment.append("velocity: read as Blender reads a domain's (units per second in "
                           "the domain object's space; --fluid-velocity physical moves it as "
                           "the simulation did)")
        comment.append(f"domain resolution {res[0]} x {res[1]} x {res[2]}, voxel i at local "
                       f"p0 + (i + 0.5) * cell: matrix = matrix_world . Translate(p0 + cell/2) "
                       f". Scale(cell) . (file index->world)^-1")
        entry['_comment'] = comment
        return entry

    def domain_fire(self, o, ds, names):
        """Why Blender's domain `o` has fire, or None. Blender allocates the
        fire fields (flame, and the temperature attribute made from it) when
        a Fire or Fire + Smoke flow takes part in the simulation, and a baked
        cache of such a domain holds a 'flame' grid."""
        if names is not None and 'flame' in names:
            return "its cache has a 'flame' grid"
        group = ds.fluid_group
        members = None if group is None else {x.name_full for x in group.all_objects}
        for f in self.render_objects():
            if f == o or (members is not None and f.name_full not in members):
                continue
            for mod in getattr(f, 'modifiers', []):
                if mod.type == 'FLUID' and mod.fluid_type == 'FLOW' and mod.show_render and \
                        mod.flow_settings.flow_type in ('FIRE', 'BOTH'):
                    return f"flow '{f.name}' is of type {mod.flow_settings.flow_type}"
        return None

    def domain_attribute(self, attr, names, what, ds, fire):
        """(grid, factor, extra keys) for a domain attribute; None or a
        reason (str) when there is no grid for it."""
        if attr == 'temperature':
            # Blender's domain `temperature` attribute is made from the flame
            # grid (rna_fluid.cc, rna_FluidModifier_temperature_grid_get):
            # ignition + flame x (max_temp - ignition) where flame > 0.01,
            # else 0; 0 everywhere without fire. The cache's `temperature`
            # grid is Mantaflow's heat x 2, > 0 where smoke is hot but not
            # burning too.
            if self.cache_temperature:
                if names is not None and 'temperature' not in names:
                    return None
                self.note(f"{what}: the cache's 'temperature' grid is exported as the "
                          "temperature (--cache-temperature); Blender renders the temperature "
                          f"it makes from the flame grid ({ds.flame_ignition:g} + flame x "
                          f"({ds.flame_max_temp:g} - {ds.flame_ignition:g}) where flame > 0.01)")
                return ('temperature', 1.0, {})
            if not fire:
                where = (f"in its Flow collection '{ds.fluid_group.name}'"
                         if ds.fluid_group is not None else "in the scene")
                return (f"but the domain has no fire (no 'flame' grid in its cache, no Fire or "
                        f"Fire + Smoke flow {where}), so Blender's temperature attribute "
                        "is 0 everywhere")
            if names is not None and 'flame' not in names:
                return ("which Blender makes from the 'flame' grid, but the cache has no "
                        "'flame' grid" + (f" (grids: {', '.join(names)})" if names else ''))
            return ('flame', 1.0, {'temperature_from_flame': [g7(ds.flame_ignition),
                                                               g7(ds.flame_max_temp)]})
        if attr in DOMAIN_GRIDS:
            g, k = DOMAIN_GRIDS[attr]
            if names is not None and g not in names:
                return None
            return (g, k, {})
        return None

    def object_material(self, o):
        slots = [s.material for s in o.material_slots if s.material is not None]
        return slots[0] if slots else None

    # -- materials

    def export_material(self, o, mat, resolve, types, comment, names, domain=False):
        """{'grids': {density_grid/temperature_grid/...}, 'material': {...}} or
        None (warned: Cycles renders no volume there). What the material
        needs that vdbphoton cannot take is warned about (once per node and
        socket) and the nearest value exported; nothing here raises."""
        what = f"{'fluid domain' if domain else 'volume object'} '{o.name}'"
        if mat is None:
            if not domain:
                # Cycles (blender/object.cpp, find_used_shaders): a Volume
                # object without a material, or an empty slot, gets
                # scene->default_volume, a Principled Volume of the node's
                # defaults (scene/shader.cpp, ShaderManager::add_default).
                comment.append("no material: Cycles' default volume shader, a Principled "
                               "Volume of the node's defaults")
                ctx = MaterialContext(self, what, "no material (Cycles' default volume shader)")
                ctx.grid_names = names
                return self.principled(ctx, DefaultPrincipledVolume(), resolve, types, names)
            self.warn(f"{what} has no material; Blender renders it black (no volume "
                      "shader); not exported")
            return None
        mname = f"material '{mat.name}'"
        nt = mat.node_tree if uses_nodes(mat) else None
        if nt is None:
            self.warn(f"{what}: {mname} uses no nodes (Cycles renders no volume with it); "
                      "not exported")
            return None
        outs = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial']
        act = [n for n in outs if n.is_active_output and n.target in ('ALL', 'CYCLES')] or \
              [n for n in outs if n.is_active_output] or outs
        node = upstream(act[0].inputs['Volume'])[0] if act else None
        if node is None:
            self.warn(f"{what}: {mname} has no volume shader (Cycles renders no volume with "
                      "it); not exported")
            return None
        out = act[0]
        if domain and out.inputs['Surface'].is_linked:
            self.warn(f"{what}: {mname} node '{follow(out.inputs['Surface']).name}' is a surface "
                      "shader, which Blender renders on the domain box; vdbphoton renders only "
                      "the volume")
        comment.append(f"{mname}, node '{node.name}'")
        ctx = MaterialContext(self, what, mname)
        ctx.grid_names = names
        if node.bl_idname == 'ShaderNodeVolumePrincipled':
            return self.principled(ctx, node, resolve, types, names)
        leaves = ctx.shader_leaves(node)
        if not leaves:
            # Warned about (the shader left out): that is the one warning.
            self.note(f"{what}: {mname} leaves no volume shader vdbphoton renders; not "
                      "exported")
            return None
        return self.raw_material(ctx, leaves, resolve, types, names)

    def attr_grid(self, ctx, attr, resolve, extra, then, resolved=UNSET):
        """(grid, factor) for Attr `attr`, or None with one warning naming
        the node, the attribute and what is exported instead (`then`).
        `resolved`: resolve(attr.name), when the caller has it already."""
        r = resolve(attr.name) if resolved is UNSET else resolved
        if r is None or isinstance(r, str):
            why = r or ("but the file has no grid of that name"
                        + (f" (grids: {', '.join(ctx.grid_names)})" if ctx.grid_names else ''))
            ctx.warn(f"node '{attr.node.name}' reads attribute '{attr.name}' ({attr.socket}), "
                     f"{why}; {then}")
            return None
        g, k, keys = r
        extra.update(keys)
        return g, k

    def zero_grid(self, ctx, types, names):
        """A grid of the file to stand for a density that is 0 everywhere
        (vdbphoton's [[volume]] reads some density grid): its first float
        grid, or None (then the volume cannot be written)."""
        if not names:
            return None
        floats = [n for n in names if types.get(n) in ('FLOAT', 'DOUBLE')]
        return (floats or [None])[0]

    # kernel/svm/attribute.h (svm_node_attr_init) and kernel/geom/volume.h
    # (volume_attribute_float4): an attribute that is not found reads 0.
    MISSING_IS_ZERO = "Cycles reads a missing attribute as 0"

    def principled(self, ctx, pv, resolve, types, names=None):
        I = pv.inputs
        grids, extra = {}, {}
        # Density: Density (x Density Attribute grid). Cycles
        # (kernel/svm/closure.h, svm_node_principled_volume) multiplies the
        # Density input by the Density Attribute where that attribute exists.
        dattr, density = ctx.scalar(pv, 'Density')
        dsock = str(I['Density Attribute'].default_value).strip()
        if dattr is not None and dsock:
            ctx.warn(f"node '{pv.name}': Density is driven by attribute '{dattr.name}' and "
                     f"Density Attribute '{dsock}' as well, which Cycles multiplies; vdbphoton "
                     f"takes one grid: '{dattr.name}' used, Density Attribute left out")
        elif dattr is None and dsock:
            dattr = Attr(dsock, pv, 'Density Attribute')
        if dattr is None:
            ctx.warn(f"node '{pv.name}': no density attribute: Blender fills the object's "
                     "bounds uniformly, which vdbphoton cannot; not exported")
            return None
        zero_density = False
        if dattr.node is pv:
            # Principled Volume's own socket: Cycles leaves the density
            # constant where the grid is missing, over the voxels of the
            # other grids the shader reads; with none, nothing renders.
            then = ("Cycles then renders no density from it (the volume's mesh is made of "
                    "the grids the shader reads that exist); density 0 exported")
        else:
            then = f"{self.MISSING_IS_ZERO}; density 0 exported"
        r = self.attr_grid(ctx, dattr, resolve, extra, then)
        if r is None:
            zero_density = True
            density = 0.0
        else:
            grids['density_grid'] = r[0]
            density *= r[1]
        col = ctx.colour(pv, 'Color')
        cattr = str(I['Color Attribute'].default_value).strip()
        if isinstance(col, Attr):
            if cattr:
                ctx.warn(f"node '{pv.name}': Color driven by attribute '{col.name}' and Color "
                         f"Attribute '{cattr}'; vdbphoton takes one grid: '{col.name}' used")
            cattr, col = col, [1.0, 1.0, 1.0]
        elif cattr:
            cattr = Attr(cattr, pv, 'Color Attribute')
        if cattr:
            if cattr.node is pv:
                then = ("Cycles leaves the colour as it is where the attribute is missing; "
                        "colour attribute not exported")
            else:
                then = f"{self.MISSING_IS_ZERO}; Color (0, 0, 0) exported"
            r = self.attr_grid(ctx, cattr, resolve, {}, then)
            if r is None:
                if cattr.node is not pv:
                    col = [0.0, 0.0, 0.0]
            elif types and types.get(r[0]) not in (None, 'VECTOR_FLOAT'):
                ctx.warn(f"colour grid '{r[0]}' is {types.get(r[0])}, not a float vector "
                         "grid; colour attribute not exported")
            else:
                grids['color_grid'] = r[0]
        absorb = ctx.colour(pv, 'Absorption Color', const_only=True)
        g = ctx.in_range(pv, 'Anisotropy', ctx.const(pv, 'Anisotropy'), 0.0, -1.0, 1.0)
        ec = ctx.colour(pv, 'Emission Color', const_only=True)
        es_attr, es = ctx.scalar(pv, 'Emission Strength')
        bi = ctx.const(pv, 'Blackbody Intensity')
        bt = ctx.colour(pv, 'Blackbody Tint', const_only=True)
        t_link, temperature = ctx.scalar(pv, 'Temperature')
        if es_attr is not None and es > 0:
            r = self.attr_grid(ctx, es_attr, resolve, extra,
                               f"{self.MISSING_IS_ZERO}; emission strength 0 exported")
            if r is None:
                es = 0.0
            else:
                grids['flame_grid'] = r[0]
                es *= r[1]
        tattr = str(I['Temperature Attribute'].default_value).strip()
        tattr = Attr(tattr, pv, 'Temperature Attribute') if tattr else None
        if t_link is not None:
            if tattr:
                ctx.warn(f"node '{pv.name}': Temperature driven by attribute '{t_link.name}' "
                         f"and Temperature Attribute '{tattr.name}', which Cycles multiplies; "
                         f"vdbphoton takes one grid: '{t_link.name}' used")
            tattr = t_link
        if bi > 0 and tattr:
            # Cycles (svm_node_principled_volume) multiplies the Temperature
            # by the Temperature Attribute only where it exists; an
            # Attribute node reading a missing grid is 0. A domain's
            # attribute that Blender makes 0 everywhere is 0.
            resolved = resolve(tattr.name)
            constant = tattr.node is pv and not isinstance(resolved, str)
            if constant:
                then = (f"Cycles then uses the Temperature {temperature:g} K alone; so does "
                        "vdbphoton (where the density is > 0)")
            elif tattr.node is pv:
                then = "blackbody emission not exported"
            else:
                then = f"{self.MISSING_IS_ZERO}; blackbody emission not exported"
            r = self.attr_grid(ctx, tattr, resolve, extra, then, resolved=resolved)
            if r is None:
                if not constant:
                    bi = 0.0
            else:
                grids['temperature_grid'] = r[0]
                temperature *= r[1]
        elif bi > 0 and types is not None:
            self.note(f"{ctx.what}: blackbody at a constant {temperature:g} K (no temperature "
                      "attribute): vdbphoton emits it only where the density is > 0, Blender "
                      "wherever the volume's bounds are")
        if zero_density:
            if not grids and (es > 0 or bi > 0):
                # Cycles builds a Volume's mesh from the grids its shader
                # reads that exist (scene/volume.cpp, create_volume_mesh):
                # none here, so not even its constant emission renders.
                self.note(f"{ctx.what}: no grid its material reads exists, so Cycles renders "
                          "nothing of it (not even its emission); emission 0 exported")
                es, bi = 0.0, 0.0
            z = self.zero_grid(ctx, types, names)
            if z is None:
                ctx.warn("the volume has no grid vdbphoton could read; not exported")
                return None
            grids['density_grid'] = z
        material = {'density': g7(density), 'color': rounded(col),
                    'absorption_color': rounded(absorb), 'anisotropy': g7(g),
                    'emission_strength': g7(es), 'emission_color': rounded(ec),
                    'blackbody_intensity': g7(bi), 'blackbody_tint': rounded(bt),
                    'temperature': g7(temperature)}
        grids.update(extra)
        return {'grids': grids, 'material': material}

    def raw_material(self, ctx, leaves, resolve, types=None, names=None):
        """Volume Scatter / Volume Absorption nodes added (or mixed)
        together, densities driven by one attribute."""
        attr = None
        sigma_s = [0.0, 0.0, 0.0]
        sigma_a = [0.0, 0.0, 0.0]
        scatter = []
        for n, w in leaves:
            a, k = ctx.scalar(n, 'Density')
            k *= w
            if a is None:
                ctx.warn(f"node '{n.name}': its Density is a constant (Blender fills the "
                         "object's bounds uniformly), which vdbphoton cannot; left out")
                continue
            if attr is not None and a != attr:
                ctx.warn(f"node '{n.name}' reads attribute '{a.name}' while another node "
                         f"reads '{attr.name}'; vdbphoton takes one grid: '{attr.name}' used "
                         "for both")
            attr = attr or a
            c = ctx.colour(n, 'Color', const_only=True)
            if n.bl_idname == 'ShaderNodeVolumeScatter':
                phase = self.scatter_phase(ctx, n)
                scatter.append((phase, k * max(c), n))
                sigma_s = [sigma_s[i] + k * c[i] for i in range(3)]
            else:
                sigma_a = [sigma_a[i] + k * max(0.0, 1.0 - c[i]) for i in range(3)]
        if attr is None:
            # Each node was warned about (a constant Density).
            self.note(f"{ctx.what}: {ctx.mname}: no node of it reads a grid; not exported")
            return None
        r = self.attr_grid(ctx, attr, resolve, {}, f"{self.MISSING_IS_ZERO}; density 0 exported")
        if r is None:
            grid, f = self.zero_grid(ctx, types or {}, names), 0.0
            if grid is None:
                ctx.warn("the volume has no grid vdbphoton could read; not exported")
                return None
        else:
            grid, f = r
        material = {'sigma_s': rounded([x * f for x in sigma_s]),
                    'sigma_a': rounded([x * f for x in sigma_a])}
        phase = self.mixed_phase(ctx, scatter)
        if phase is not None:
            material['phase'] = phase
        return {'grids': {'density_grid': grid}, 'material': material}

    def scatter_phase(self, ctx, n):
        """A Volume Scatter node's phase function as a [volume.material]
        phase table, from its `phase` (Blender 4.3 and later; HG before) and
        the sockets that phase shows. None (warned) where a socket is driven
        by something other than a constant."""
        phase = getattr(n, 'phase', 'HENYEY_GREENSTEIN')
        if phase not in SCATTER_PHASES:
            self.warn(f"{ctx.what}: {ctx.mname} node '{n.name}': phase {phase} is not "
                      "supported; isotropic used")
            return {'type': 'isotropic'}
        kind, params = SCATTER_PHASES[phase]
        table = {'type': kind}
        for key, sock, default, lo, hi in params:
            # Blender 5 finds no socket by a name the phase hides (KeyError),
            # so only the phase's own sockets are read.
            if n.inputs.get(sock) is None:
                self.warn(f"{ctx.what}: {ctx.mname} node '{n.name}': phase {phase} has no "
                          f"'{sock}' input; Blender's default {default:g} used")
                v = default
            else:
                v = ctx.const(n, sock)
            table[key] = ctx.in_range(n, sock, v, default, lo, hi)
        return table

    def mixed_phase(self, ctx, scatter):
        """The phase table of Volume Scatter nodes added together
        ([(table, weight, node)], weight = Density x max(Color)), or None for
        isotropic (the default). Henyey-Greenstein lobes of different g make
        an hg_mix weighted as Cycles weighs its closures; one phase (or the
        same table everywhere) is written as it is; other mixtures take the
        phase of the node that scatters most, with one warning."""
        live = [x for x in scatter if x[1] > 0] or scatter
        if not live:
            return None
        if all(p['type'] == 'hg' for p, _, _ in live):
            gvals = sorted(set(p['g'] for p, _, _ in live))
            if len(gvals) == 1:
                return {'type': 'hg', 'g': gvals[0]} if gvals[0] != 0.0 else None
            tot = sum(w for _, w, _ in live)
            return {'type': 'hg_mix', 'lobes': [
                {'g': p['g'], 'weight': g7(w / tot if tot > 0 else 1.0 / len(live))}
                for p, w, _ in live]}
        top = max(live, key=lambda x: x[1])
        if any(p != top[0] for p, _, _ in live):
            others = ', '.join(f"'{n.name}' ({phase_label(p)})" for p, _, n in live
                               if n is not top[2])
            self.warn(f"{ctx.what}: {ctx.mname} node '{top[2].name}' ({phase_label(top[0])}) "
                      f"is added to Volume Scatter nodes of other phases ({others}), which "
                      "vdbphoton cannot mix; its phase, the one that scatters most, is used "
                      "for all")
        if top[0] == {'type': 'hg', 'g': 0.0}:
            return None
        return top[0]

    # -- everything

    def export(self):
        sc = self.scene
        doc = {'header': [f"vdbphoton scene exported by tools/blender/vdbphoton_export.py from "
                          f"{os.path.basename(self.blend_path) or '(unsaved)'}, scene '{sc.name}', "
                          f"Blender {bpy.app.version_string}"],
               'light': [], 'volume': [], 'environment': None}
        doc['render'] = self.export_render()
        doc['camera'] = self.export_camera()
        objects = self.render_objects()
        doc['light'] = self.export_lights(objects)
        doc['environment'] = self.export_world()
        for o in objects:
            if o.type not in ('CAMERA', 'LIGHT') and invisible_to_rays(o):
                # A fluid flow emitter, say: Cycles renders nothing of it.
                if o.type == 'VOLUME' or any(m.type == 'FLUID' and m.fluid_type == 'DOMAIN'
                                             for m in getattr(o, 'modifiers', [])):
                    self.note(f"object '{o.name}' is invisible to every ray type (Object > "
                              "Visibility > Ray Visibility); not exported")
                continue
            if o.type == 'VOLUME':
                v = self.export_volume_object(o)
                if v is not None:
                    doc['volume'].append(v)
                continue
            dom = None
            for mod in o.modifiers:
                if mod.type == 'FLUID' and mod.fluid_type == 'DOMAIN':
                    dom = mod
            if dom is not None and dom.show_render:
                ds = dom.domain_settings
                if ds.domain_type == 'GAS':
                    v = self.export_domain(o, dom)
                    if v is not None:
                        doc['volume'].append(v)
                else:
                    self.warn(f"fluid domain '{o.name}' is a liquid domain; not supported "
                              "(Blender renders its mesh)")
                continue
            self.check_other(o)
        doc['mesh'] = self.export_meshes(objects)
        if not doc['volume'] and not doc['mesh']:
            raise ExportError(f"nothing to export: scene '{sc.name}' has no Volume object or "
                              "smoke domain that could be exported, and no mesh")
        if not self.frames_arg and not any('#' in v['file'] or '{frame' in v['file']
                                           for v in doc['volume']):
            # A still (every volume one file): every frame of the range is
            # the same image, so the scene is the current frame, as F12.
            doc['render']['frames'] = str(sc.frame_current)
            self.note(f"scene '{sc.name}': no volume changes from frame to frame; exported as "
                      f"frame {sc.frame_current} alone, not the range "
                      f"{frame_range_text(sc.frame_start, sc.frame_end, sc.frame_step)}")
        return doc

    def check_other(self, o):
        """Objects Blender renders that are neither volumes nor meshes:
        warned about. Meshes (and curves, surfaces, metaballs, text) are
        exported by export_meshes(), but one whose materials are volumes
        alone is a homogeneous volume in Blender, not a surface."""
        if o.type in ('CAMERA', 'LIGHT', 'EMPTY', 'ARMATURE', 'LATTICE', 'SPEAKER',
                      'LIGHT_PROBE', 'LIGHTPROBE'):
            return
        kind = OBJECT_KINDS.get(o.type, o.type)
        role = ''
        for mod in getattr(o, 'modifiers', []):
            if mod.type == 'FLUID' and mod.fluid_type in ('FLOW', 'EFFECTOR'):
                role = f' (fluid {mod.fluid_type.lower()})'
        if o.type in SURFACE_TYPES:
            self.check_materials(o, kind, role)
            return
        self.warn(f"{kind} object '{o.name}'{role} is rendered by Blender, but vdbphoton renders "
                  "only volumes and meshes; not exported")

    def check_materials(self, o, kind, role=''):
        """What Cycles renders of geometry object `o` by its materials:
        'surface', 'holdout' (every surface a Holdout shader), 'volume' (only
        volume shaders: a homogeneous volume, warned about) or 'none' (no
        shader at all: nothing). Warns once per object."""
        surfaces, holdouts, volumes = 0, 0, []
        slots = [s.material for s in getattr(o, 'material_slots', [])]
        if not slots or any(m is None for m in slots):
            surfaces += 1  # Blender's default surface
        for m in slots:
            if m is None:
                continue
            nt = m.node_tree if uses_nodes(m) else None
            if nt is None:
                surfaces += 1
                continue
            outs = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial']
            act = [n for n in outs if n.is_active_output and n.target in ('ALL', 'CYCLES')] or \
                  [n for n in outs if n.is_active_output] or outs
            if not act:
                continue
            if act[0].inputs['Surface'].is_linked:
                surfaces += 1
                if follow(act[0].inputs['Surface']).bl_idname == 'ShaderNodeHoldout':
                    holdouts += 1
            if act[0].inputs['Volume'].is_linked:
                volumes.append((m.name, follow(act[0].inputs['Volume']).name))
        key = o.original.name_full if o.original is not None else o.name_full
        first = key not in self.checked
        self.checked.add(key)
        name = o.original.name if o.original is not None else o.name
        if first:
            for mname, nname in volumes:
                if surfaces:
                    self.warn(f"{kind} object '{name}'{role}: material '{mname}' node '{nname}' "
                              f"fills the {kind} with a homogeneous volume, which vdbphoton "
                              "does not support; only its surface is exported (as a mesh)")
                else:
                    self.warn(f"{kind} object '{name}'{role}: material '{mname}' node '{nname}' "
                              f"fills the {kind} with a homogeneous volume, which vdbphoton "
                              "does not support; not exported")
        if not surfaces:
            return 'volume' if volumes else 'none'
        return 'holdout' if holdouts == surfaces else 'surface'

    # -- meshes

    def needs_meshes(self, objects):
        """Whether anything among the rendered objects may make a mesh (so
        that the scene must be evaluated): geometry, instancers, particle
        systems, Geometry Nodes."""
        for o in objects:
            if o.type in ('CAMERA', 'LIGHT') or invisible_to_rays(o) or is_fluid_domain(o):
                continue
            if o.type in SURFACE_TYPES or o.instance_type != 'NONE':
                return True
            if any(m.type in ('NODES', 'PARTICLE_SYSTEM') for m in getattr(o, 'modifiers', [])):
                return True
        return False

    def render_depsgraph(self, work):
        """Calls work(depsgraph) with the scene evaluated as Blender renders
        it (render visibility, modifiers' render settings, the render levels
        of subdivision) at the current frame. Blender's Python has no way to
        make a render depsgraph but a render, so this renders the view layer
        with a helper engine that draws nothing (Blender's Render Result
        image is then that empty render). If that fails, the viewport's
        depsgraph, with a warning."""
        sc = self.scene
        result = {}
        layer = self.view_layer.name

        class EvalEngine(bpy.types.RenderEngine):
            bl_idname = 'VDBPHOTON_EXPORT_EVAL'
            bl_label = 'vdbphoton export (evaluation)'
            bl_use_postprocess = False

            def render(self, depsgraph):
                if 'done' in result or depsgraph.view_layer_eval.name != layer:
                    return
                result['done'] = True
                try:
                    result['value'] = work(depsgraph)
                except Exception as e:  # noqa: BLE001 (handed back to the exporter)
                    result['error'] = e

        engine = sc.render.engine
        try:
            bpy.utils.register_class(EvalEngine)
        except (RuntimeError, ValueError):
            pass
        try:
            sc.render.engine = EvalEngine.bl_idname
            bpy.ops.render.render(layer=layer, scene=sc.name)
        except (RuntimeError, TypeError) as e:
            result.setdefault('failed', str(e).strip().splitlines()[-1] if str(e).strip()
                              else type(e).__name__)
        finally:
            sc.render.engine = engine
            try:
                bpy.utils.unregister_class(EvalEngine)
            except RuntimeError:
                pass
        if 'error' in result:
            raise result['error']
        if 'done' in result:
            return result['value']
        why = result.get('failed', 'the render pipeline did not run (a sequencer strip?)')
        self.warn(f"meshes: the scene could not be evaluated as Blender renders it ({why}); "
                  "they are exported as the viewport shows them (viewport visibility and "
                  "modifier levels)")
        try:
            dg = bpy.context.evaluated_depsgraph_get() if bpy.context.scene == sc else None
        except AttributeError:
            dg = None
        dg = dg or self.view_layer.depsgraph
        return work(dg)

    def export_meshes(self, objects):
        """[[mesh]] entries for every geometry instance Blender renders as a
        surface (meshes, curves, surfaces, metaballs, text; modifiers,
        collection instances, Geometry Nodes and particle instances
        included), from the render depsgraph. Their triangles are kept in
        self.meshes until write_meshes()."""
        if not self.needs_meshes(objects):
            return []
        t0 = time.time()
        if self.depsgraph is not None:
            found = self.mesh_instances(self.depsgraph)
        else:
            found = self.render_depsgraph(self.mesh_instances)
        if found:
            keys = {f['key'] for f in found}
            tris = sum(len(self.meshes[k]['tri']) for k in keys)
            n, nm = self.instances, len({k[0] for k in keys})
            self.note(f"meshes: {n} instance{'s' if n != 1 else ''} of "
                      f"{nm} distinct mesh{'es' if nm != 1 else ''} ({tris} "
                      f"triangles) read in {time.time() - t0:.2f} s")
        return self.mesh_entries(found)

    def mesh_instances(self, depsgraph):
        """What Cycles renders as a surface: every instance of the depsgraph
        whose geometry is a mesh (Blender 5 evaluates curves, surfaces,
        metaballs and text into a mesh instance of their own object, which
        is what Cycles renders; where Blender does not, the object's
        to_mesh()). Returns the instances (name, matrix, flags, the key of
        their triangles in self.meshes). Flags as Cycles takes them
        (intern/cycles/blender/object.cpp): holdout = the instancer's
        holdout_get(view layer), or the object's own when it is not an
        instance (Object > Visibility > Holdout, or in a collection set to
        Holdout in the view layer; not in its child collections: measured in
        Cycles 5.0.1); shadow catcher = the object's or its instancer's; ray
        visibility = the object's and its instancer's; in an Indirect Only
        collection, invisible to the camera."""
        vl = depsgraph.view_layer_eval
        found, curves, own = [], [], set()
        told = set()
        counts = {}
        for inst in depsgraph.object_instances:
            if not inst.show_self:
                continue
            ob = inst.object
            is_inst = inst.is_instance
            parent = inst.parent if is_inst else ob
            orig = ob.original if ob.original is not None else ob
            if ob.type in CURVE_TYPES and not is_inst:
                curves.append(ob)
                continue
            if ob.type != 'MESH' or not isinstance(ob.data, bpy.types.Mesh):
                # (Objects of the view layer are warned about by
                # check_other; instances of them here.)
                if ob.type in ('CURVES', 'POINTCLOUD', 'GPENCIL', 'GREASEPENCIL') and \
                        is_inst and orig.name_full not in told:
                    told.add(orig.name_full)
                    by = f" (instanced by '{parent.name}')"
                    self.warn(f"{OBJECT_KINDS.get(ob.type, ob.type)} object '{orig.name}'{by} "
                              "is rendered by Blender, but vdbphoton renders only volumes and "
                              "meshes; not exported")
                continue
            if is_inst and orig == parent.original:
                # A curve's (text's, ...) own surface.
                own.add(orig.name_full)
                is_inst = False
            if is_fluid_domain(orig):
                continue
            kind = OBJECT_KINDS.get(orig.type, orig.type)
            if is_inst:
                base = f'{parent.name}/{orig.name}'
                counts[base] = counts.get(base, 0) + 1
                name = f'{base} #{counts[base]}'
                what = f"{kind} '{orig.name}' instanced by '{parent.name}'"
            else:
                name = orig.name
                what = f"{kind} object '{orig.name}'"
            self.add_instance(found, ob, parent, orig, vl, inst.matrix_world, name, what, kind)
        for ob in curves:
            orig = ob.original if ob.original is not None else ob
            if orig.name_full in own:
                continue
            kind = OBJECT_KINDS.get(ob.type, ob.type)
            self.add_instance(found, ob, ob, orig, vl, ob.matrix_world, orig.name,
                              f"{kind} object '{orig.name}'", kind)
        return found

    def add_instance(self, found, ob, parent, orig, vl, matrix, name, what, kind):
        """Appends instance `ob` (evaluated; `parent` its instancer, or `ob`)
        to `found`, one entry per material slot its faces use, unless Cycles
        renders nothing of it."""
        vis = {k: bool(getattr(ob, 'visible_' + k, True)) and
               bool(getattr(parent, 'visible_' + k, True)) for k in VISIBILITY_KEYS}
        holdout = bool(parent.holdout_get(view_layer=vl))
        if not holdout and parent.indirect_only_get(view_layer=vl):
            vis['camera'] = False
        if not any(vis.values()):
            return  # Cycles does not render it at all
        shading = self.check_materials(ob, kind)
        if shading == 'volume':
            return
        if ob.type == 'MESH':
            key = ('data', ob.data.as_pointer())
        else:
            key = ('object', orig.as_pointer())
        mats = slot_materials(ob)
        if key not in self.mesh_parts:
            self.mesh_parts[key] = self.triangles(ob, what, orig.name, len(mats), key)
        parts = self.mesh_parts[key]
        if parts is None:
            return
        m = matrix.copy()
        if not all(math.isfinite(m[i][j]) for i in range(4) for j in range(4)) or \
                abs(m.to_3x3().determinant()) < 1e-30:
            self.warn(f"{what}: its transform is not invertible (a scale of 0?) or not "
                      "finite; not exported")
            return
        self.instances += 1
        used = [mats[min(i, len(mats) - 1)] if mats else None for i in parts]
        for idx, mat in zip(parts, used):
            kind_, table = self.surfaces.read(orig.name, mat)
            if kind_ == 'skip':
                continue
            if kind_ == 'material':
                table = self.check_uvs(orig.name, mat, table, (key, idx))
            mname = mat.name if mat is not None else 'no material'
            if used.count(mat) > 1:
                mname += f', slot {idx + 1}'
            found.append({'key': (key, idx),
                          'name': name if len(parts) == 1 else f'{name} [{mname}]',
                          'what': what if len(parts) == 1 else f"{what}, material '{mname}'",
                          'matrix': m,
                          'holdout': holdout or shading == 'holdout' or kind_ == 'holdout',
                          'shadow_catcher': bool(ob.is_shadow_catcher or
                                                 parent.is_shadow_catcher),
                          'visibility': vis, 'objects': (orig, parent.original or parent),
                          # A Holdout shader is black to every other ray.
                          'material': table if kind_ == 'material' else
                          BLACK_SURFACE() if kind_ == 'holdout' else None})

    def check_uvs(self, obj_name, mat, table, part_key):
        """A texture needs the mesh's UV map: without one (Blender reads the
        texture at (0, 0)) the texture's socket value is written instead; a
        texture asking for another UV map than the active render one (the
        one exported) is warned about."""
        uv_name = self.meshes[part_key].get('uv_name')
        asked = self.surfaces.uv_maps_used(obj_name, mat)
        tex = [k for k, v in table.items() if isinstance(v, TextureRef)]
        if not tex:
            return table
        told = (obj_name, mat.name_full, 'uv')
        if uv_name is None:
            if told not in self.uv_told:
                self.uv_told.add(told)
                t = table[tex[0]]
                self.warn(f"{t.what} reads the image through a UV map, but the mesh has "
                          "none (Blender reads the image at (0, 0)); "
                          f"'{tex[0].replace('_texture', '')}' = {t.fallback} used")
            return {(k.replace('_texture', '') if k in tex else k):
                    (v.fallback if k in tex else v) for k, v in table.items()}
        other = sorted(n for n in asked if n not in ('', uv_name))
        if other and told not in self.uv_told:
            self.uv_told.add(told)
            self.warn(f"mesh object '{obj_name}': material '{mat.name}' reads UV map "
                      f"'{other[0]}', but only the active render UV map '{uv_name}' is "
                      "exported; textures read through it")
        return table

    def triangles(self, ob, what, label, nslots, key):
        """Reads evaluated object `ob` in its object space: its loop
        triangles (read in bulk), the normals Blender shades with and the
        active render UV map, vertices split where their corners differ, and
        the triangles split by material slot (clamped to the slots, as
        Cycles does). Stores each part {'co': float32 (n, 3), 'tri': int32
        (m, 3), 'n': float32 (n, 3) or None (flat-shaded), 'uv': float32 (n,
        2) or None, 'label', 'uv_name'} in self.meshes[(key, slot)] and
        returns the slots, or None (warned about) when there is nothing to
        render."""
        import numpy as np
        me, temporary = None, False
        try:
            if ob.type == 'MESH':
                me = ob.data
            else:
                me = ob.to_mesh()
                temporary = True
        except RuntimeError as e:
            self.warn(f"{what}: Blender cannot make a mesh of it ({e}); not exported")
            return None
        try:
            if me is None or len(me.polygons) == 0:
                if ob.type in CURVE_TYPES or (me is not None and len(me.vertices) == 0 and any(
                        m.type == 'NODES' for m in getattr(ob.original, 'modifiers', []))):
                    # A curve without bevel or extrusion renders nothing,
                    # only a metaball family's base object holds its
                    # surface, and Geometry Nodes that make only instances
                    # leave the object's own mesh empty.
                    return None
                self.warn(f"{what} has no faces (nothing to render); not exported")
                return None
            co, tri, loops, corner_vert, mi, normals, uv, uv_name = read_mesh_arrays(me)
        finally:
            if temporary:
                ob.to_mesh_clear()
        bad = ~np.isfinite(co).all(axis=1)
        repeated = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
        nonfinite = bad[tri].any(axis=1)
        if bad.any():
            co[bad] = 0.0
            nv, nt = int(bad.sum()), int(nonfinite.sum())
            self.warn(f"{what}: {nv} vert{'ices are' if nv != 1 else 'ex is'} not a finite "
                      f"number; the {nt} triangle{'s' if nt != 1 else ''} using "
                      f"{'them' if nv != 1 else 'it'} {'are' if nt != 1 else 'is'} left out")
        if (repeated & ~nonfinite).any():
            n = int((repeated & ~nonfinite).sum())
            self.warn(f"{what}: {n} triangle{'s' if n != 1 else ''} with a repeated vertex "
                      "(no area) left out")
        if (repeated | nonfinite).any():
            keep = ~(repeated | nonfinite)
            tri, loops, mi = tri[keep], loops[keep], mi[keep]
        if len(tri) == 0:
            self.warn(f"{what} has no triangles left to render; not exported")
            return None
        for name, arr in (('normals', normals[1] if normals else None), ('UVs', uv)):
            if arr is not None and not np.isfinite(arr).all():
                n = int((~np.isfinite(arr).all(axis=1)).sum())
                self.warn(f"{what}: {n} {name} not a finite number; set to 0")
                arr[~np.isfinite(arr)] = 0.0
        co, tri, n, uv = split_corners(co, tri, loops, corner_vert, normals, uv)
        slot = np.clip(mi, 0, max(nslots, 1) - 1)
        used = np.unique(slot)
        parts = []
        for idx in used.tolist():
            if len(used) == 1:
                pco, ptri, pn, puv = co, tri, n, uv
            else:
                t = tri[slot == idx]
                keep = np.unique(t)
                remap = np.full(len(co), -1, dtype=np.int32)
                remap[keep] = np.arange(len(keep), dtype=np.int32)
                pco, ptri = co[keep], remap[t]
                pn = n[keep] if n is not None else None
                puv = uv[keep] if uv is not None else None
            plabel = label
            if len(used) > 1:
                m = slot_materials(ob)
                plabel = f"{label}_{m[idx].name if m and m[idx] is not None else 'no_material'}"
            self.meshes[(key, idx)] = {'co': np.ascontiguousarray(pco),
                                       'tri': np.ascontiguousarray(ptri), 'n': pn, 'uv': puv,
                                       'label': plabel, 'uv_name': uv_name}
            parts.append(idx)
        return parts

    def mesh_entries(self, found):
        """The [[mesh]] entries (one per instance; instances of one mesh
        share its file). More than MAX_MESH_ENTRIES instances (a Geometry
        Nodes scatter, say) are merged, in world space, into one mesh per
        combination of flags, so that the scene file stays small."""
        import numpy as np
        if len(self.frames) > 1:
            self.warn_animated(found)
        if found and self.scene.render.use_motion_blur:
            self.note("meshes are rendered without motion blur (vdbphoton does not move them)")
        if len(found) > MAX_MESH_ENTRIES:
            groups = {}
            for f in found:
                flags = (f['holdout'], f['shadow_catcher'], tuple(f['visibility'].values()),
                         material_key(f['material']))
                groups.setdefault(flags, []).append(f)
            merged_meshes = {}
            out = []
            for k, (flags, fs) in enumerate(groups.items()):
                ntri = sum(len(self.meshes[f['key']]['tri']) for f in fs)
                if ntri > MAX_MERGED_TRIANGLES:
                    raise ExportError(f"{len(found)} mesh instances with {ntri} triangles: too "
                                      f"many to merge into one mesh (at most "
                                      f"{MAX_MERGED_TRIANGLES}); realize fewer instances")
                key = ('merged', k)
                merged_meshes[key] = merge_world([(self.meshes[f['key']], f['matrix'])
                                                  for f in fs])
                merged_meshes[key]['label'] = f'merged_{k + 1}'
                f0 = fs[0]
                out.append({'key': key, 'name': f"{len(fs)} instances ({f0['name']}, ...)",
                            'what': f"{len(fs)} instances, merged", 'matrix': Matrix.Identity(4),
                            'holdout': f0['holdout'], 'shadow_catcher': f0['shadow_catcher'],
                            'visibility': f0['visibility'], 'objects': (),
                            'material': f0['material']})
            self.warn(f"{len(found)} mesh instances: merged into {len(out)} world-space "
                      f"mesh{'es' if len(out) != 1 else ''} (one per combination of holdout, "
                      f"shadow catcher, ray visibility and material), since more than "
                      f"{MAX_MESH_ENTRIES} [[mesh]] entries would make the scene file too large")
            self.meshes = merged_meshes
            found = out
        entries = []
        for f in found:
            e = {'_comment': f"Blender {f['what']}", '_key': f['key'], 'file': None,
                 'name': f['name'],
                 'transform': {'matrix': matrix_rows(f['matrix'])},
                 'holdout': f['holdout'], 'shadow_catcher': f['shadow_catcher']}
            off = {k: False for k, v in f['visibility'].items() if not v}
            if off:
                e['visibility'] = off
            if f['material'] is not None:
                e['material'] = f['material']
            entries.append(e)
        used = {e['_key'] for e in entries}
        self.meshes = {k: v for k, v in self.meshes.items() if k in used and v is not None}
        return entries

    def warn_animated(self, found):
        """A warning per animated object among the meshes' objects: their
        meshes are exported as they are at the current frame, for every
        frame."""
        told = set()
        for f in found:
            for o in f['objects']:
                if o.name_full in told or not is_animated(o):
                    continue
                told.add(o.name_full)
                self.warn(f"object '{o.name}' is animated, but its mesh is exported as it is at "
                          f"frame {self.scene.frame_current} for every frame of "
                          f"{compress_frames(self.frames)} (vdbphoton does not move meshes over "
                          "a sequence; export a frame at a time for that)")

    def write_meshes(self, entries, toml_path):
        """Writes each distinct mesh once as a binary PLY into
        '<stem>_meshes/' beside the scene file and fills the entries'
        `file` (relative to the scene file); returns the file names."""
        if not entries:
            return set()
        toml_path = os.path.abspath(toml_path)
        stem = os.path.splitext(os.path.basename(toml_path))[0]
        folder_name = f'{stem}_meshes'
        folder = os.path.join(os.path.dirname(toml_path), folder_name)
        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as e:
            raise ExportError(f'cannot make the mesh folder {folder}: {e.strerror or e}') from None
        t0 = time.time()
        names, files = set(), {}
        for e in entries:
            k = e['_key']
            if k not in files:
                d = self.meshes[k]
                base = re.sub(r'[^A-Za-z0-9._-]+', '_', d['label']).strip('._') or 'mesh'
                name, n = base, 1
                while name.lower() in names:
                    n += 1
                    name = f'{base}_{n}'
                names.add(name.lower())
                write_ply(os.path.join(folder, name + '.ply'), d['co'], d['tri'], d.get('n'),
                          d.get('uv'))
                files[k] = f'{folder_name}/{name}.ply'
            e['file'] = files[k]
            if 'material' in e:
                e['material'] = self.resolve_textures(e['material'], folder, folder_name,
                                                      names)
        self.note(f"meshes: {len(files)} PLY file{'s' if len(files) != 1 else ''} written to "
                  f"{folder} in {time.time() - t0:.2f} s")
        return {f.rsplit('/', 1)[1] for f in files.values()} | set(self.texture_files.values())

    def resolve_textures(self, material, folder, folder_name, names):
        """The material with each TextureRef made { file, colorspace }: an
        image file vdbphoton reads, by its absolute path; a packed image
        written into the mesh folder; another format converted there (PNG,
        or EXR for float images). Where that fails, the socket's colour
        (warned)."""
        out = {}
        for k, v in material.items():
            if not isinstance(v, TextureRef):
                out[k] = v
                continue
            ik = v.image.name_full
            if ik not in self.texture_paths:
                try:
                    self.texture_paths[ik] = self.texture_file(v, folder, folder_name, names)
                except (OSError, RuntimeError, ExportError) as e:
                    self.warn(f"{v.what}: cannot write the image into {folder} ({e}); "
                              f"'{k.replace('_texture', '')}' = {v.fallback} used")
                    self.texture_paths[ik] = None
            path = self.texture_paths[ik]
            if path is None:
                out[k.replace('_texture', '')] = v.fallback
            else:
                out[k] = {'file': path, 'colorspace': v.colorspace}
        return out

    def texture_file(self, t, folder, folder_name, names):
        img = t.image
        src = bpy.path.abspath(img.filepath, library=img.library) if img.filepath else ''
        base = os.path.basename(src) or img.name
        stem, ext = os.path.splitext(base)
        stem = re.sub(r'[^A-Za-z0-9._-]+', '_', stem).strip('._') or 'texture'
        if img.packed_file is not None:
            data = bytes(img.packed_file.data)
            ext = {b'\x89PNG': '.png', b'\xff\xd8\xff': '.jpg', b'v/1\x01': '.exr'}.get(
                next((m for m in (b'\x89PNG', b'\xff\xd8\xff', b'v/1\x01')
                      if data.startswith(m)), None), ext.lower())
            if ext in TEXTURE_EXTENSIONS:
                import hashlib
                digest = hashlib.sha256(data).hexdigest()
                if digest in self.packed_written:  # the same image packed twice
                    self.texture_files[img.name_full] = self.packed_written[digest]
                    return f'{folder_name}/{self.packed_written[digest]}'
                name = self.texture_name(stem, ext, names)
                self.packed_written[digest] = name
                path = os.path.join(folder, name)
                tmp = os.path.join(folder, f'.{name}.{os.getpid()}.tmp')
                with open(tmp, 'wb') as f:
                    f.write(data)
                os.replace(tmp, path)
                self.note(f"{t.what} is packed in the .blend; written to {path}")
                self.texture_files[img.name_full] = name
                return f'{folder_name}/{name}'
        elif ext.lower() in TEXTURE_EXTENSIONS:
            if os.path.dirname(os.path.abspath(src)) == os.path.abspath(folder):
                self.texture_files[img.name_full] = os.path.basename(src)  # not stale
            return src
        # Another format: saved as PNG (or EXR for float images) by Blender.
        ext = '.exr' if img.is_float else '.png'
        name = self.texture_name(stem, ext, names)
        path = os.path.join(folder, name)
        c = img.copy()
        try:
            if not c.has_data:
                c.pixels[0]  # noqa: B018 (loads the copy's buffer from the file)
            c.filepath_raw = path
            c.file_format = 'OPEN_EXR' if img.is_float else 'PNG'
            c.save()
        finally:
            bpy.data.images.remove(c)
        if not os.path.isfile(path):
            raise ExportError('Blender wrote no file')
        self.note(f"{t.what}: {'packed ' if img.packed_file is not None else ''}"
                  f"{os.path.basename(src) or 'image'} is not PNG, JPEG or EXR; converted to "
                  f"{path}")
        self.texture_files[img.name_full] = name
        return f'{folder_name}/{name}'

    @staticmethod
    def texture_name(stem, ext, names):
        name, n = stem + ext, 1
        while name.lower() in names:
            n += 1
            name = f'{stem}_{n}{ext}'
        names.add(name.lower())
        return name


# Volume Scatter's phases (Blender 4.3 and later) -> [volume.material] phase
# tables: the type and, per key, (key, the node's socket, Blender's default,
# the range vdbphoton accepts, which is the socket's range in Blender's UI;
# docs/scene.md). Cycles clamps further inside (|g| <= 0.999, Backscatter
# <= 0.499, IOR >= 1.001) and so does vdbphoton, alike.
SCATTER_PHASES = {
    'HENYEY_GREENSTEIN': ('hg', (('g', 'Anisotropy', 0.0, -1.0, 1.0),)),
    'FOURNIER_FORAND': ('fournier_forand', (('backscatter', 'Backscatter', 0.1, 0.0, 0.5),
                                            ('ior', 'IOR', 1.33, 1.0, 2.0))),
    'DRAINE': ('draine', (('g', 'Anisotropy', 0.0, -1.0, 1.0),
                          ('alpha', 'Alpha', 0.5, 0.0, 500.0))),
    'RAYLEIGH': ('rayleigh', ()),
    'MIE': ('mie', (('diameter', 'Diameter', 20.0, 0.0, 50.0),)),
}


def phase_label(table):
    """A phase table as a warning names it: `fournier_forand backscatter 0.1
    ior 1.33`."""
    return ' '.join([table['type']] + [f"{k} {v:g}" for k, v in table.items() if k != 'type'])


class Attr:
    """A grid a material reads: its name and the node that names it (an
    Attribute node, or the Principled Volume whose attribute socket it is)."""

    def __init__(self, name, node, socket):
        self.name, self.node, self.socket = name, node, socket

    def __eq__(self, other):
        return isinstance(other, Attr) and self.name == other.name

    def __hash__(self):
        return hash(self.name)


class _Socket:
    is_linked = False
    links = ()

    def __init__(self, name, value):
        self.name = self.identifier = name
        self.default_value = value


class DefaultPrincipledVolume:
    """Cycles' default volume shader (scene/shader.cpp,
    ShaderManager::add_default: a PrincipledVolumeNode, nothing linked),
    with the node's defaults (scene/shader_nodes.cpp,
    NODE_DEFINE(PrincipledVolumeNode) and its constructor), read as a
    Principled Volume node is."""
    name = 'Principled Volume'
    bl_label = 'Principled Volume'
    bl_idname = 'ShaderNodeVolumePrincipled'
    DEFAULTS = (('Color', (0.5, 0.5, 0.5, 1.0)), ('Color Attribute', ''), ('Density', 1.0),
                ('Density Attribute', 'density'), ('Anisotropy', 0.0),
                ('Absorption Color', (0.0, 0.0, 0.0, 1.0)), ('Emission Strength', 0.0),
                ('Emission Color', (1.0, 1.0, 1.0, 1.0)), ('Blackbody Intensity', 0.0),
                ('Blackbody Tint', (1.0, 1.0, 1.0, 1.0)), ('Temperature', 1000.0),
                ('Temperature Attribute', 'temperature'))

    def __init__(self):
        self.inputs = {k: _Socket(k, v) for k, v in self.DEFAULTS}


class MaterialContext:
    """Reads the inputs of volume shader nodes as vdbphoton can take them: a
    constant, or an attribute (grid) times a constant. Whatever else feeds
    an input is one warning naming object, material, the node that is
    unsupported (the deepest one along the link, not the first node
    downstream of it) and the socket it drives, and the nearest value is
    used instead: that socket's own value, as if the link were not there,
    or on an input that takes a grid, the attribute the unsupported node
    reads (passed through unchanged). The readers never fail."""

    def __init__(self, ex, what, mname):
        self.ex, self.what, self.mname = ex, what, mname
        self.grid_names = None
        self.told = set()

    def warn(self, msg):
        self.ex.warn(f"{self.what}: {self.mname} {msg}")

    def unsupported(self, bad, into, sock, used):
        """One warning per unsupported node and socket it drives."""
        key = (bad.name, into.name, sock)
        if key in self.told:
            return
        self.told.add(key)
        self.warn(f"node '{bad.name}' ({bad.bl_label}) drives '{sock}' of node '{into.name}'; "
                  f"not supported: {used}")

    @staticmethod
    def own_value(sock):
        v = sock.default_value
        try:
            return float(v)
        except TypeError:
            c = rgb3(v)
            return sum(c) / 3.0

    def upstream_attr(self, node):
        """The first Attribute node (Geometry type) upstream of `node`, or
        None."""
        seen, todo = set(), [(node, ())]
        while todo and len(seen) < 200:
            n, stack = todo.pop(0)
            for s in n.inputs:
                src, out, st = upstream(s, stack)
                if src is None or src.as_pointer() in seen:
                    continue
                seen.add(src.as_pointer())
                if src.bl_idname == 'ShaderNodeAttribute' and src.attribute_type == 'GEOMETRY' \
                        and src.attribute_name.strip():
                    return Attr(src.attribute_name.strip(), src, out.name)
                todo.append((src, st))
        return None

    def _scalar(self, node, sock, allow_attr, stack=(), depth=0):
        """(Attr or None, factor, problem or None) for input socket `sock`
        of `node`; problem: (unsupported node, node it drives, socket name,
        what was used)."""
        src, out, stack = upstream(sock, stack)
        if src is None:
            v = out if out is not None else sock
            return None, self.own_value(v), None
        if depth > 64:
            return None, self.own_value(sock), (src, node, sock.name, 'a chain too deep')
        t = src.bl_idname
        if t == 'ShaderNodeValue':
            return None, float(out.default_value), None
        if allow_attr and t == 'ShaderNodeAttribute' and out.name in ('Fac', 'Factor') and \
                src.attribute_type == 'GEOMETRY' and src.attribute_name.strip():
            return Attr(src.attribute_name.strip(), src, out.name), 1.0, None
        if t == 'ShaderNodeMath' and src.operation == 'MULTIPLY' and not src.use_clamp:
            a = self._scalar(src, src.inputs[0], allow_attr, stack, depth + 1)
            b = self._scalar(src, src.inputs[1], allow_attr, stack, depth + 1)
            prob = a[2] or b[2]
            if a[0] is not None and b[0] is not None:
                # Two grids multiplied: vdbphoton takes one.
                return a[0], a[1] * b[1], prob or (
                    src, node, sock.name, f"attribute '{a[0].name}' used, '{b[0].name}' left out "
                    "(vdbphoton multiplies a density by one grid)")
            return a[0] or b[0], a[1] * b[1], prob
        # Unsupported: the nearest value.
        if allow_attr:
            at = self.upstream_attr(src)
            if at is not None:
                return at, 1.0, (src, node, sock.name,
                                 f"the attribute '{at.name}' it reads is used in its place")
        v = self.own_value(sock)
        return None, v, (src, node, sock.name, f"the link is left out ('{sock.name}' = {v:g} "
                                               f"of node '{node.name}' used)")

    def scalar(self, node, name):
        """(Attr or None, factor): an input that may read a grid."""
        attr, k, prob = self._scalar(node, node.inputs[name], True)
        if prob is not None:
            self.unsupported(*prob)
        return attr, k

    def const(self, node, name):
        """A constant input (a Value node counts)."""
        sock = node.inputs[name]
        attr, k, prob = self._scalar(node, sock, False)
        if prob is not None:
            self.unsupported(*prob)
        if attr is not None:
            return self.own_value(sock)
        return k

    def in_range(self, node, name, v, default, lo, hi):
        """A constant of input `name` within [lo, hi], the range vdbphoton
        accepts for it: clamped (NaN: Blender's default), with a warning."""
        if not math.isfinite(v):
            self.ex.warn(f"{self.what}: {self.mname} node '{node.name}': '{name}' is {v}; "
                         f"Blender's default {default:g} used")
            return g7(default)
        x = g7(v)
        if lo <= x <= hi:
            return x
        c = g7(min(max(x, lo), hi))
        self.ex.warn(f"{self.what}: {self.mname} node '{node.name}': '{name}' = {x:g} is "
                     f"outside [{lo:g}, {hi:g}], the socket's range in Blender and the one "
                     f"vdbphoton accepts; {c:g} used")
        return c

    def colour(self, node, name, const_only=False):
        """[r, g, b], or an Attr (the Color output of an Attribute node)."""
        s = node.inputs[name]
        src, out, _ = upstream(s)
        if src is None:
            return rgb3((out if out is not None else s).default_value)
        if src.bl_idname == 'ShaderNodeRGB':
            return rgb3(out.default_value)
        if not const_only and src.bl_idname == 'ShaderNodeAttribute' and out.name == 'Color' \
                and src.attribute_type == 'GEOMETRY' and src.attribute_name.strip():
            return Attr(src.attribute_name.strip(), src, out.name)
        c = rgb3(s.default_value)
        self.unsupported(src, node, name, f"the link is left out ('{name}' = "
                                          f"({c[0]:g}, {c[1]:g}, {c[2]:g}) of node "
                                          f"'{node.name}' used)")
        return c

    def shader_leaves(self, node, weight=1.0, stack=()):
        """[(Volume Scatter or Volume Absorption node, weight)] that `node`
        adds (Add Shader) or mixes (Mix Shader with a constant Fac).
        Other shaders are left out with a warning; their light is missing."""
        if node.bl_idname in ('ShaderNodeVolumeScatter', 'ShaderNodeVolumeAbsorption'):
            return [(node, weight)]
        if node.bl_idname in ('ShaderNodeAddShader', 'ShaderNodeMixShader'):
            ins = list(node.inputs)
            weights = [1.0, 1.0]
            if node.bl_idname == 'ShaderNodeMixShader':
                f = min(max(self.const(node, 'Fac'), 0.0), 1.0)
                ins, weights = ins[1:3], [1.0 - f, f]
            out = []
            for s, w in zip(ins, weights):
                src, _, st = upstream(s, stack)
                if src is not None and w > 0.0:
                    out.extend(self.shader_leaves(src, weight * w, st))
            return out
        self.warn(f"node '{node.name}' ({node.bl_label}) is not supported (a Principled "
                  "Volume, or Volume Scatter and Volume Absorption nodes added or mixed, are); "
                  "it is left out")
        return []


# ------------------------------------------------------- surface materials

# Blender's image colour spaces -> [mesh.material] texture colorspace.
SRGB_SPACES = ('sRGB',)
LINEAR_SPACES = ('Linear Rec.709', 'Non-Color', 'Raw', 'Linear', 'Utility - Raw',
                 'Utility - Linear - sRGB')
# Image files vdbphoton reads (by extension); others are converted.
TEXTURE_EXTENSIONS = ('.png', '.jpg', '.jpeg', '.exr')
# Cycles renders a missing image (and an Image Texture without one) magenta.
MISSING_IMAGE = [1.0, 0.0, 1.0]
# Principled BSDF inputs (Blender 4/5) that vdbphoton shades, as [mesh.material] keys.
PRINCIPLED_SCALARS = (('Roughness', 'roughness'), ('Metallic', 'metallic'), ('IOR', 'ior'),
                      ('Specular IOR Level', 'specular_ior_level'))
PRINCIPLED_COLOURS = (('Specular Tint', 'specular_tint'), ('Emission Color', 'emission_color'))
# Principled BSDF inputs whose effect vdbphoton does not render, with the value
# that switches them off: a different value (or a link) is warned about.
PRINCIPLED_OFF = (('Alpha', 1.0, 'transparency'), ('Diffuse Roughness', 0.0, 'diffuse roughness'),
                  ('Subsurface Weight', 0.0, 'subsurface scattering'),
                  ('Anisotropic', 0.0, 'anisotropy'),
                  ('Transmission Weight', 0.0, 'transmission'), ('Coat Weight', 0.0, 'coat'),
                  ('Sheen Weight', 0.0, 'sheen'), ('Thin Film Thickness', 0.0, 'thin film'))
# Other shader nodes: what vdbphoton writes instead (with a warning).
NEAREST_SHADER = {
    'ShaderNodeBsdfGlossy': ('a Principled BSDF of Metallic 1', 'metal'),
    'ShaderNodeBsdfAnisotropic': ('a Principled BSDF of Metallic 1', 'metal'),
    'ShaderNodeBsdfMetallic': ('a Principled BSDF of Metallic 1', 'metal'),
    'ShaderNodeBsdfGlass': ('an opaque Principled BSDF of its colour, roughness and IOR',
                            'dielectric'),
    'ShaderNodeBsdfRefraction': ('an opaque Principled BSDF of its colour, roughness and IOR',
                                 'dielectric'),
    'ShaderNodeBsdfTranslucent': ('a Diffuse BSDF of its colour', 'diffuse'),
    'ShaderNodeBsdfSheen': ('a Diffuse BSDF of its colour', 'diffuse'),
    'ShaderNodeBsdfToon': ('a Diffuse BSDF of its colour', 'diffuse'),
    'ShaderNodeSubsurfaceScattering': ('a Diffuse BSDF of its colour', 'diffuse'),
    'ShaderNodeBsdfHair': ('a Diffuse BSDF of its colour', 'diffuse'),
    'ShaderNodeBsdfHairPrincipled': ('a Diffuse BSDF of its colour', 'diffuse'),
    'ShaderNodeBackground': ('an Emission shader', 'emission'),
}


def upstream(sock, stack=()):
    """What feeds input socket `sock` of a node tree, as Blender evaluates
    it: through reroutes, muted nodes' pass-through links, into node groups
    (to their Group Output) and out of them (from a Group Input to the group
    node's socket; `stack` holds the group nodes entered). Returns (node,
    output socket, stack) for a node, (None, socket, stack) when the value is
    that socket's own (unlinked) value, (None, None, stack) when nothing
    feeds it (a muted node without pass-through, an empty group)."""
    for _ in range(10000):
        links = [lk for lk in sock.links if lk.is_valid and not getattr(lk, 'is_muted', False)] \
            if sock.is_linked else []
        if not links:
            return None, sock, stack
        node, out = links[0].from_node, links[0].from_socket
        if node.bl_idname == 'NodeReroute':
            sock = node.inputs[0]
            continue
        if node.mute:
            through = [lk for lk in node.internal_links
                       if lk.to_socket.identifier == out.identifier]
            if not through:
                return None, None, stack
            sock = through[0].from_socket
            continue
        if node.bl_idname in ('ShaderNodeGroup', 'NodeGroup') or \
                (node.type == 'GROUP' and getattr(node, 'node_tree', None) is not None):
            nt = node.node_tree
            outs = [n for n in nt.nodes if n.bl_idname == 'NodeGroupOutput'] if nt else []
            go = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
            s = next((x for x in go.inputs if x.identifier == out.identifier), None) \
                if go is not None else None
            if s is None:
                return None, None, stack
            sock, stack = s, stack + (node,)
            continue
        if node.bl_idname == 'NodeGroupInput':
            if not stack:
                return None, None, stack
            s = next((x for x in stack[-1].inputs if x.identifier == out.identifier), None)
            if s is None:
                return None, None, stack
            sock, stack = s, stack[:-1]
            continue
        return node, out, stack
    return None, None, stack


class TextureRef:
    """An image a material reads, resolved to a file when the meshes are
    written (Exporter.texture_file)."""

    def __init__(self, image, colorspace, fallback, what):
        self.image, self.colorspace, self.fallback, self.what = image, colorspace, fallback, what

    def key(self):
        return ('texture', self.image.name_full, self.colorspace)


def material_key(m):
    """A hashable form of a [mesh.material] table (textures by image)."""
    if m is None:
        return None

    def k(v):
        if isinstance(v, dict):
            return tuple(sorted((a, k(b)) for a, b in v.items()))
        if isinstance(v, list):
            return tuple(k(x) for x in v)
        if isinstance(v, TextureRef):
            return v.key()
        return v
    return k(m)


class SurfaceReader:
    """A mesh's Blender material -> its [mesh.material] table, as Cycles
    shades it: the surface output (the Material Output active for Cycles)
    followed to a Principled BSDF, Diffuse BSDF or Emission shader, constant
    inputs from the sockets, an Image Texture on a colour through the UV map.
    Everything else is one warning naming object, material, node and socket,
    with the nearest supported shading written."""

    def __init__(self, ex):
        self.ex = ex
        self.cache = {}

    def read(self, obj_name, mat):
        """(kind, table): ('material', {...}), ('default', None) (Cycles'
        default surface: no [mesh.material]), ('holdout', None) (a Holdout
        shader), ('skip', None) (nothing vdbphoton can render: left out).
        Warnings once per object and material."""
        if mat is None:
            return 'default', None
        key = (obj_name, mat.name_full)
        if key not in self.cache:
            self.what = f"mesh object '{obj_name}': material '{mat.name}'"
            self.uv_maps = set()
            try:
                r = self._read(mat)
            except Exception as e:  # noqa: BLE001 (a warning, never a traceback)
                self.ex.warn(f"{self.what} could not be read ({type(e).__name__}: {e}); "
                             "exported with Blender's default surface")
                r = ('default', None)
            self.cache[key] = (r, set(self.uv_maps))
        return self.cache[key][0]

    def uv_maps_used(self, obj_name, mat):
        """The UV map names the material's textures ask for ('' = the active
        render map)."""
        if mat is None:
            return set()
        return self.cache.get((obj_name, mat.name_full), (None, set()))[1]

    # -- helpers

    def warn(self, msg):
        self.ex.warn(f"{self.what}{msg}")

    @staticmethod
    def nname(node, stack):
        inside = ''.join(f" in group '{g.name}'" for g in reversed(stack))
        return f"node '{node.name}'{inside}"

    def _read(self, mat):
        nt = mat.node_tree if uses_nodes(mat) else None
        if nt is None:
            # A material without nodes: Cycles renders its viewport colour
            # as a diffuse surface.
            c = rgb3(mat.diffuse_color)
            return 'material', {'type': 'diffuse', 'color': self.finite_rgb(
                c, [0.8, 0.8, 0.8], "(no nodes) viewport colour"), 'roughness': 0.0}
        outs = [n for n in nt.nodes if n.bl_idname == 'ShaderNodeOutputMaterial']
        act = [n for n in outs if n.is_active_output and n.target in ('ALL', 'CYCLES')] or \
              [n for n in outs if n.target in ('ALL', 'CYCLES')] or \
              [n for n in outs if n.is_active_output] or outs
        if not act:
            self.ex.note(f"{self.what} has no Material Output; Blender renders it black")
            return 'material', BLACK_SURFACE()
        out = act[0]
        if out.inputs['Displacement'].is_linked:
            src, _, st = upstream(out.inputs['Displacement'])
            if src is not None:
                self.warn(f" {self.nname(src, st)} ({src.bl_label}) drives 'Displacement' of "
                          f"node '{out.name}': displacement and bump are not supported; "
                          "exported without them")
        src, sock, st = upstream(out.inputs['Surface'])
        if src is None:
            if out.inputs['Volume'].is_linked:
                return 'skip', None  # a volume only (check_materials warned)
            self.ex.note(f"{self.what} has no surface shader; Blender renders it black")
            return 'material', BLACK_SURFACE()
        return self.shader(src, sock, st, out, 'Surface')

    def shader(self, node, sock, stack, into, into_socket, depth=0):
        t = node.bl_idname
        nn = self.nname(node, stack)
        if depth > 50:
            self.warn(f" {nn}: shaders nested too deep; Blender's default surface used")
            return 'default', None
        if t == 'ShaderNodeBsdfPrincipled':
            return 'material', self.principled(node, stack)
        if t == 'ShaderNodeBsdfDiffuse':
            return 'material', self.diffuse(node, stack)
        if t == 'ShaderNodeEmission':
            return 'material', self.emission(node, stack)
        if t == 'ShaderNodeHoldout':
            return 'holdout', None
        if t in ('ShaderNodeMixShader', 'ShaderNodeAddShader'):
            return self.mix(node, stack, depth)
        if t == 'ShaderNodeBsdfTransparent':
            self.warn(f" {nn} (Transparent BSDF): transparent surfaces are not supported; the "
                      "mesh is left out")
            return 'skip', None
        if t in NEAREST_SHADER:
            desc, kind = NEAREST_SHADER[t]
            self.warn(f" {nn} ({node.bl_label}) is not supported; exported as {desc}")
            return 'material', self.nearest(node, stack, kind)
        self.warn(f" {nn} ({node.bl_label}) drives '{into_socket}' of node '{into.name}' and "
                  "is not a shader vdbphoton supports; exported with Blender's default surface")
        return 'default', None

    def mix(self, node, stack, depth):
        """Mix Shader: a constant factor of 0 or 1 is its one input exactly;
        otherwise the input with the larger weight (the first when the factor
        is linked), warned about. Add Shader: a Principled BSDF plus an
        Emission is the Principled BSDF with that emission (exact without
        coat and sheen); otherwise its first input, warned about."""
        nn = self.nname(node, stack)
        shaders = [s for s in node.inputs if s.type == 'SHADER']
        srcs = [upstream(s, stack) for s in shaders]
        names = [f"'{s[0].name}'" if s[0] is not None else 'nothing' for s in srcs]
        if node.bl_idname == 'ShaderNodeMixShader':
            fs = upstream(node.inputs[0], stack)
            if fs[0] is None and fs[1] is not None:
                fac = float(fs[1].default_value)
                pick = 0 if fac < 0.5 else 1
                if not (fac <= 0.0 or fac >= 1.0):
                    self.warn(f" {nn} (Mix Shader) mixes {names[0]} and {names[1]} by its "
                              f"Factor {fac:g}, which vdbphoton does not support; exported as "
                              f"{names[pick]} alone")
            else:
                pick = 0
                what = f"node '{fs[0].name}'" if fs[0] is not None else 'a link'
                self.warn(f" {nn} (Mix Shader) mixes {names[0]} and {names[1]} by {what} "
                          "into its 'Factor', which vdbphoton does not support; exported as "
                          f"{names[0]} alone")
        else:
            kinds = [s[0].bl_idname if s[0] is not None else None for s in srcs]
            if sorted(kinds, key=str) == sorted(['ShaderNodeBsdfPrincipled', 'ShaderNodeEmission']):
                p = kinds.index('ShaderNodeBsdfPrincipled')
                e = 1 - p
                kind, table = self.shader(srcs[p][0], srcs[p][1], srcs[p][2], node, 'Shader',
                                          depth + 1)
                em = self.emission(srcs[e][0], srcs[e][2])
                if kind == 'material' and table.get('emission_strength', 0.0) == 0.0:
                    table['emission_color'] = em['color']
                    table['emission_strength'] = em['strength']
                    return kind, table
            pick = 0
            self.warn(f" {nn} (Add Shader) adds {names[0]} and {names[1]}, which vdbphoton "
                      f"does not support; exported as {names[0]} alone")
        if srcs[pick][0] is None:
            other = 1 - pick
            if srcs[other][0] is None:
                return 'material', BLACK_SURFACE()
            pick = other
        n, s, st = srcs[pick]
        return self.shader(n, s, st, node, 'Shader', depth + 1)

    def finite(self, v, default, what):
        if math.isfinite(v):
            return v
        self.warn(f" {what} is {v}; Blender's default {default:g} used")
        return default

    def finite_rgb(self, c, default, what):
        if all(math.isfinite(x) for x in c):
            return rounded(c)
        self.warn(f" {what} is {c}; Blender's default {default} used")
        return list(default)

    def scalar(self, node, stack, name):
        """A number input: its value, or a Value node's; anything else is
        warned about and the socket's own value used."""
        s = node.inputs[name]
        nn = self.nname(node, stack)
        default = float(s.default_value)
        src, out, st = upstream(s, stack)
        if src is None:
            v = float(out.default_value) if out is not None else default
        elif src.bl_idname == 'ShaderNodeValue':
            v = float(src.outputs[0].default_value)
        else:
            self.warn(f" {self.nname(src, st)} ({src.bl_label}) drives '{name}' of {nn}, "
                      f"which vdbphoton does not support; '{name}' = {g7(default)} used")
            v = default
        return g7(self.finite(v, BLENDER_DEFAULTS.get(name, 0.0), f"{nn}: '{name}'"))

    def colour(self, node, stack, name, texture_key=None):
        """A colour input: its value, an RGB node's, or (when texture_key)
        an Image Texture through the UV map -> (rgb or None, TextureRef or
        None). Anything else is warned about and the socket's own value
        used."""
        s = node.inputs[name]
        nn = self.nname(node, stack)
        default = rgb3(s.default_value)
        src, out, st = upstream(s, stack)
        if src is None:
            c = rgb3(out.default_value) if out is not None and \
                hasattr(out, 'default_value') and len(out.default_value) >= 3 else default
        elif src.bl_idname == 'ShaderNodeRGB':
            c = rgb3(src.outputs[0].default_value)
        elif src.bl_idname == 'ShaderNodeTexImage' and texture_key is not None:
            return self.image_texture(src, out, st, node, stack, name, default)
        else:
            extra = ''
            if src.bl_idname == 'ShaderNodeTexImage':
                extra = ' (image textures are read on Base Color and a Diffuse BSDF\'s Color)'
            self.warn(f" {self.nname(src, st)} ({src.bl_label}) drives '{name}' of {nn}, "
                      f"which vdbphoton does not support{extra}; '{name}' = "
                      f"{rounded(default, 4)} used")
            c = default
        return self.finite_rgb(c, BLENDER_DEFAULTS.get(name, [0.8, 0.8, 0.8]),
                               f"{nn}: '{name}'"), None

    def image_texture(self, tex, out, stack, node, node_stack, name, default):
        """An Image Texture node feeding colour `name` of `node` -> (None,
        TextureRef), or a constant colour (warned) when vdbphoton cannot
        read it as Cycles does."""
        tn = self.nname(tex, stack)
        into = f"'{name}' of {self.nname(node, node_stack)}"
        img = tex.image
        if out.identifier != 'Color':
            self.warn(f" {tn} (Image Texture): its {out.name} output drives {into}, which "
                      f"vdbphoton does not support; '{name}' = {rounded(default, 4)} used")
            return rounded(default), None
        if img is None:
            self.warn(f" {tn} (Image Texture) has no image: Blender renders it magenta; "
                      f"{into} = {MISSING_IMAGE} used")
            return list(MISSING_IMAGE), None
        iname = f"image '{img.name}'"
        if img.source == 'GENERATED':
            c = rgb3(img.generated_color)
            how = 'its colour' if img.generated_type == 'BLANK' else \
                f"its base colour (Blender draws a {img.generated_type.lower().replace('_', ' ')})"
            self.warn(f" {tn} (Image Texture): {iname} is generated in Blender, not a file; "
                      f"{into} = {how} {rounded(c, 4)} used")
            return self.finite_rgb(c, [0.8, 0.8, 0.8], f"{tn}: {iname} colour"), None
        if img.source != 'FILE':
            self.warn(f" {tn} (Image Texture): {iname} is a {img.source.lower()} (only single "
                      f"image files are supported); {into} = {rounded(default, 4)} used")
            return rounded(default), None
        if img.packed_file is None:
            path = bpy.path.abspath(img.filepath, library=img.library)
            if not os.path.isfile(path):
                self.warn(f" {tn} (Image Texture): {iname} file {path} does not exist: Blender "
                          f"renders it magenta; {into} = {MISSING_IMAGE} used")
                return list(MISSING_IMAGE), None
        cs_name = img.colorspace_settings.name
        if cs_name == 'Working Space':
            cs_name = getattr(getattr(bpy.data, 'colorspace', None), 'working_space',
                              'Linear Rec.709')
        if cs_name in SRGB_SPACES:
            cs = 'srgb'
        elif cs_name in LINEAR_SPACES or img.colorspace_settings.is_data:
            cs = 'linear'
        else:
            cs = 'srgb' if not img.is_float else 'linear'
            self.warn(f" {tn} (Image Texture): {iname} colour space '{cs_name}' is not "
                      f"supported (sRGB, Linear Rec.709, Non-Color are); read as \"{cs}\"")
        if tex.projection != 'FLAT':
            self.warn(f" {tn} (Image Texture): projection {tex.projection.title()} is not "
                      "supported; read as Flat through the UV map")
        if tex.extension != 'REPEAT':
            self.warn(f" {tn} (Image Texture): extension {tex.extension.title()} is not "
                      "supported; read as Repeat")
        if tex.interpolation != 'Linear':
            self.warn(f" {tn} (Image Texture): interpolation {tex.interpolation} is not "
                      "supported; read as Linear")
        self.uv_chain(tex, stack)
        return None, TextureRef(img, cs, rounded(default), f"{self.what} {tn}, {iname}")

    def uv_chain(self, tex, stack):
        """The texture's coordinates must be the UV map: the Vector input
        unlinked, or a UV Map node / Texture Coordinate's UV, through Mapping
        nodes that change nothing."""
        sock, st = tex.inputs['Vector'], stack
        tn = self.nname(tex, stack)
        into_node, into_name = tex, 'Vector'
        while True:
            src, out, st2 = upstream(sock, st)
            if src is None:
                if out is sock or out is None:
                    self.uv_maps.add('')
                    return
                self.warn(f" {tn} (Image Texture): its coordinates are a group input's "
                          "constant; read through the UV map")
                self.uv_maps.add('')
                return
            sn = self.nname(src, st2)
            if src.bl_idname == 'ShaderNodeUVMap':
                if getattr(src, 'from_instancer', False):
                    self.warn(f" {sn} (UV Map) reads the instancer's UV map, which is not "
                              "supported; the mesh's own used")
                self.uv_maps.add(src.uv_map)
                return
            if src.bl_idname == 'ShaderNodeTexCoord' and out.identifier == 'UV':
                if getattr(src, 'from_instancer', False):
                    self.warn(f" {sn} (Texture Coordinate) reads the instancer's UV map, which "
                              "is not supported; the mesh's own used")
                self.uv_maps.add('')
                return
            if src.bl_idname == 'ShaderNodeMapping':
                I = src.inputs
                ident = src.vector_type in ('POINT', 'TEXTURE', 'VECTOR')
                for k, want in (('Location', 0.0), ('Rotation', 0.0), ('Scale', 1.0)):
                    if k not in I or not I[k].enabled:
                        continue
                    if I[k].is_linked or any(abs(float(x) - want) > 1e-7
                                             for x in I[k].default_value):
                        ident = False
                if not ident:
                    self.warn(f" {sn} (Mapping) transforms the coordinates of {tn}, which "
                              "vdbphoton does not support; read without it")
                sock, st, into_node, into_name = I['Vector'], st2, src, 'Vector'
                if not sock.is_linked:
                    self.warn(f" {sn} (Mapping) has no input vector (Blender reads the "
                              f"texture at (0, 0, 0)); read through the UV map instead")
                    self.uv_maps.add('')
                    return
                continue
            what = f"{out.name} of " if out is not None and len(src.outputs) > 1 else ''
            self.warn(f" {sn} ({src.bl_label}) drives '{into_name}' of "
                      f"{self.nname(into_node, st)}: {what}texture coordinates other than the "
                      "UV map are not supported; read through the UV map")
            self.uv_maps.add('')
            return

    def check_off(self, node, stack, inputs):
        """Inputs whose effect vdbphoton does not render: warned about when
        they are not at the value that switches them off."""
        nn = self.nname(node, stack)
        for name, off, feature in inputs:
            if name not in node.inputs:
                continue
            s = node.inputs[name]
            src, out, st = upstream(s, stack)
            if src is not None:
                self.warn(f" {self.nname(src, st)} ({src.bl_label}) drives '{name}' of {nn}: "
                          f"{feature} is not supported; exported without it")
            elif out is not None and float(out.default_value) != off:
                self.warn(f" {nn}: '{name}' is {g7(out.default_value)}: {feature} is not "
                          "supported; exported without it")

    def check_normal(self, node, stack, names=('Normal',)):
        for name in names:
            if name in node.inputs:
                src, _, st = upstream(node.inputs[name], stack)
                if src is not None:
                    self.warn(f" {self.nname(src, st)} ({src.bl_label}) drives '{name}' of "
                              f"{self.nname(node, stack)}: normal maps and bump are not "
                              "supported; exported with the mesh's normals")

    # -- shaders

    def principled(self, node, stack):
        m = {'type': 'principled'}
        c, tex = self.colour(node, stack, 'Base Color', texture_key='base_color_texture')
        if tex is not None:
            m['base_color_texture'] = tex
        else:
            m['base_color'] = c
        if 'Specular IOR Level' not in node.inputs:
            # Blender 3's Principled BSDF (Specular, Clearcoat, ...).
            self.warn(f" {self.nname(node, stack)} is a Principled BSDF of Blender 3, whose "
                      "inputs differ from Blender 4's: Base Color, Roughness, Metallic, IOR "
                      "and the emission are read, the rest left at Blender 4's defaults (open "
                      "and save the file in Blender 4 or later for a faithful export)")
            for sock, key in PRINCIPLED_SCALARS + (('Emission Strength', 'emission_strength'),):
                m[key] = self.scalar(node, stack, sock) if sock in node.inputs else \
                    BLENDER_DEFAULTS[sock]
            m['specular_tint'] = [1.0, 1.0, 1.0]
            m['emission_color'] = self.colour(node, stack, 'Emission')[0] \
                if 'Emission' in node.inputs else [1.0, 1.0, 1.0]
            return m
        for sock, key in PRINCIPLED_SCALARS:
            m[key] = self.scalar(node, stack, sock)
        for sock, key in PRINCIPLED_COLOURS:
            m[key] = self.colour(node, stack, sock)[0]
        m['emission_strength'] = self.scalar(node, stack, 'Emission Strength')
        self.check_off(node, stack, PRINCIPLED_OFF)
        self.check_normal(node, stack, ('Normal',))
        if getattr(node, 'distribution', 'MULTI_GGX') != 'MULTI_GGX':
            self.warn(f" {self.nname(node, stack)}: distribution {node.distribution} is not "
                      "supported; exported as Multiscatter GGX (Blender's default)")
        return m

    def diffuse(self, node, stack):
        m = {'type': 'diffuse'}
        c, tex = self.colour(node, stack, 'Color', texture_key='color_texture')
        if tex is not None:
            m['color_texture'] = tex
        else:
            m['color'] = c
        m['roughness'] = self.scalar(node, stack, 'Roughness')
        self.check_normal(node, stack)
        return m

    def emission(self, node, stack):
        c, _ = self.colour(node, stack, 'Color')
        return {'type': 'emission', 'color': c, 'strength': self.scalar(node, stack, 'Strength')}

    def nearest(self, node, stack, kind):
        """The supported shading nearest to an unsupported shader node."""
        cname = 'Base Color' if 'Base Color' in node.inputs else 'Color'
        c = self.colour(node, stack, cname)[0] if cname in node.inputs else [0.8, 0.8, 0.8]
        rough = self.scalar(node, stack, 'Roughness') if 'Roughness' in node.inputs else 0.5
        if kind == 'diffuse':
            return {'type': 'diffuse', 'color': c, 'roughness': 0.0}
        if kind == 'emission':
            return {'type': 'emission', 'color': c,
                    'strength': self.scalar(node, stack, 'Strength')}
        m = {'type': 'principled', 'base_color': c, 'roughness': rough,
             'metallic': 1.0 if kind == 'metal' else 0.0}
        if kind == 'dielectric' and 'IOR' in node.inputs:
            m['ior'] = self.scalar(node, stack, 'IOR')
        return m


def BLACK_SURFACE():
    """What Cycles renders of a material without a surface shader: black."""
    return {'type': 'diffuse', 'color': [0.0, 0.0, 0.0], 'roughness': 0.0}


# Blender's defaults of the shader inputs read (the value written for NaN).
BLENDER_DEFAULTS = {'Base Color': [0.8, 0.8, 0.8], 'Roughness': 0.5, 'Metallic': 0.0,
                    'IOR': 1.5, 'Specular IOR Level': 0.5, 'Specular Tint': [1.0, 1.0, 1.0],
                    'Emission Color': [1.0, 1.0, 1.0], 'Emission Strength': 0.0,
                    'Color': [0.8, 0.8, 0.8], 'Strength': 1.0}


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


def invisible_to_rays(o):
    """Cycles renders nothing of an object whose ray visibilities are all
    off (Blender 3.0+: Object > Visibility > Ray Visibility)."""
    return all(hasattr(o, k) and not getattr(o, k) for k in RAY_VISIBILITY)


def uses_nodes(idblock):
    """Blender 5 always uses nodes (use_nodes is deprecated there)."""
    if bpy.app.version >= (5, 0, 0):
        return idblock.node_tree is not None
    return bool(idblock.use_nodes)


def follow(socket, with_socket=False):
    """The node (and output socket) feeding `socket`, through reroutes."""
    link = socket.links[0]
    node, out = link.from_node, link.from_socket
    while node.bl_idname == 'NodeReroute' and node.inputs[0].is_linked:
        link = node.inputs[0].links[0]
        node, out = link.from_node, link.from_socket
    return (node, out) if with_socket else node


def scale_material(mat, f):
    """Multiplies a material's extinction and emission by f."""
    if 'density' in mat:
        mat['density'] = g7(mat['density'] * f)
        mat['emission_strength'] = g7(mat['emission_strength'] * f)
        mat['blackbody_tint'] = rounded([x * f for x in mat['blackbody_tint']])
    else:
        for k in ('sigma_s', 'sigma_a'):
            mat[k] = rounded([x * f for x in mat[k]])


def volume_attribute(attr, names):
    """A Volume object's attribute is the grid of that name."""
    if names is not None and attr not in names:
        return None
    return attr, 1.0, {}


def volume_sequence_frame(vol, frame):
    """Blender's BKE_volume_time: the file number shown at scene `frame`,
    or None where the sequence shows nothing."""
    dur = vol.frame_duration
    if dur <= 0:
        return None
    f = frame - vol.frame_start + 1
    mode = vol.sequence_mode
    if mode == 'CLIP':
        if f < 1 or f > dur:
            return None
    elif mode == 'EXTEND':
        f = min(max(f, 1), dur)
    elif mode == 'REPEAT':
        f %= dur
        if f < 0:
            f += dur
        if f == 0:
            f = dur
    elif mode == 'PING_PONG':
        pp = 2 * (dur - 1)
        if pp <= 0:
            f = 1
        else:
            f %= pp
            if f < 0:
                f += pp
            if f == 0:
                f = pp
            if f > dur:
                f = dur - (f - dur)
    return f + vol.frame_offset


def domain_placement(o, ds):
    """Blender's manta_set_domain_from_mesh for a non-adaptive gas domain:
    resolution per axis, local cell size and the index -> local matrix
    (voxel i at p0 + (i + 0.5) * cell), computed in float32 as Blender does."""
    verts = o.data.vertices
    if len(verts) == 0:
        raise ExportError(f"fluid domain '{o.name}' has no vertices")
    lo = [min(f32(v.co[i]) for v in verts) for i in range(3)]
    hi = [max(f32(v.co[i]) for v in verts) for i in range(3)]
    size_local = [f32(hi[i] - lo[i]) for i in range(3)]
    scale = [f32(x) for x in o.scale]
    size = [f32(abs(f32(size_local[i] * scale[i]))) for i in range(3)]
    res_max = int(ds.resolution_max)
    if size[0] >= max(size[1], size[2]):
        axis = 0
    elif size[1] >= max(size[0], size[2]):
        axis = 1
    else:
        axis = 2
    sc = f32(res_max / size[axis])
    res = [0, 0, 0]
    for i in range(3):
        res[i] = res_max if i == axis else max(int(f32(f32(size[i] * sc) + 0.5)), 4)
    cell = [f32(size_local[i] / res[i]) for i in range(3)]
    # Mantaflow writes the cache with a uniform voxel of the largest world
    # dimension / resolution (checked against the file when there is one).
    dx = size[axis] / res_max
    m = Matrix.Identity(4)
    for i in range(3):
        m[i][i] = cell[i]
        m[i][3] = lo[i] + 0.5 * cell[i]
    return {'res': res, 'cell': cell, 'p0': lo, 'dx': dx, 'index_to_local': m}


def blender_output_pattern(filepath, blend_path):
    """Blender's output path with the frame as '#' (Blender appends four
    digits when the path has no '#'), absolute."""
    p = filepath or '//'
    if p.startswith('//'):
        base = os.path.dirname(blend_path) if blend_path else os.getcwd()
        p = os.path.join(base, p[2:])
    p = os.path.abspath(p) + (os.sep if p.endswith(('/', os.sep)) else '')
    d, name = os.path.split(p)
    if '#' not in name:
        stem, ext = os.path.splitext(name)
        if ext.lower() in ('.exr', '.png', '.jpg', '.tif', '.tiff'):
            name = stem
        name += '####'
    return os.path.join(d, name)


# ------------------------------------------------------------- writing

def write_scene(path, text):
    """Atomic write (temporary name, then rename); raises ExportError."""
    path = os.path.abspath(path)
    d = os.path.dirname(path)
    if not os.path.isdir(d):
        raise ExportError(f"cannot write {path}: folder {d} does not exist")
    tmp = os.path.join(d, f'.{os.path.basename(path)}.{os.getpid()}.tmp')
    try:
        with open(tmp, 'w', encoding='utf-8') as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise ExportError(f'cannot write {path}: {e.strerror or e}') from None


def export_scene(path, scene=None, view_layer=None, warn=None, **kw):
    """Exports `scene` (default: the context's) to `path`, its meshes as PLY
    files into '<stem>_meshes/' beside it; returns the Exporter (its
    .warnings). `depsgraph`: the render depsgraph when there is one (the
    render engine's). Raises ExportError."""
    scene = scene or bpy.context.scene
    if view_layer is None:
        try:
            view_layer = bpy.context.view_layer if bpy.context.scene == scene else None
        except AttributeError:
            view_layer = None
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise ExportError(f"cannot write {os.path.abspath(path)}: folder {d} does not exist")
    if kw.get('depsgraph') is None:
        # Objects made or moved by a script have their matrix_world once
        # the view layer is evaluated.
        try:
            (view_layer or scene.view_layers[0]).update()
        except (RuntimeError, AttributeError):
            pass
    try:
        ex = Exporter(scene, view_layer=view_layer, warn=warn, scene_path=path, **kw)
        doc = ex.export()
        written = ex.write_meshes(doc['mesh'], path)
        write_scene(path, to_toml(doc))
        remove_stale_meshes(path, written)
    except ExportError:
        raise
    except Exception as e:  # noqa: BLE001 (one clean error, never a traceback)
        raise ExportError(internal_error(e)) from None
    return ex


def internal_error(e):
    """An unexpected exception as one line: its type, message and where in
    this file it was raised."""
    import traceback
    tb = [f for f in traceback.extract_tb(e.__traceback__)
          if os.path.basename(f.filename) == os.path.basename(__file__)] or \
        traceback.extract_tb(e.__traceback__)
    where = f' (vdbphoton_export.py line {tb[-1].lineno}, {tb[-1].name})' if tb else ''
    msg = str(e).strip().splitlines()[-1] if str(e).strip() else ''
    return (f"the export failed: {type(e).__name__}{': ' + msg if msg else ''}{where}; "
            "please report it")


def remove_stale_meshes(path, written):
    """Removes the .ply files (and textures) of an earlier export from the
    scene's mesh folder ('<stem>_meshes/', which belongs to the scene file)
    that this export did not write."""
    stem = os.path.splitext(os.path.basename(path))[0]
    folder = os.path.join(os.path.dirname(os.path.abspath(path)), f'{stem}_meshes')
    if not os.path.isdir(folder):
        return
    for name in os.listdir(folder):
        if name.lower().endswith(('.ply',) + TEXTURE_EXTENSIONS) and name not in written:
            try:
                os.unlink(os.path.join(folder, name))
            except OSError:
                pass


# ------------------------------------------------------------------ add-on

try:
    from bpy_extras.io_utils import ExportHelper
except ImportError:  # pragma: no cover
    ExportHelper = object


class EXPORT_SCENE_OT_vdbphoton(bpy.types.Operator, ExportHelper):
    """Export Volume objects, smoke domains, camera, lights and world as a vdbphoton scene"""
    bl_idname = 'export_scene.vdbphoton'
    bl_label = 'Export vdbphoton scene'
    bl_options = {'PRESET'}
    filename_ext = '.toml'
    filter_glob: bpy.props.StringProperty(default='*.toml', options={'HIDDEN'})
    frames: bpy.props.StringProperty(
        name='Frames', default='',
        description="Frame list like 1-40 or 1-3,5,7-20:2 (empty: the scene's range)")
    output: bpy.props.StringProperty(
        name='Output', default='',
        description="EXR path with {frame:04} or #### (empty: the scene's output path); "
                    "relative to the scene file")
    cache_temperature: bpy.props.BoolProperty(
        name="Cache's temperature grid", default=False,
        description="For smoke domains with fire, use the cache's 'temperature' grid (heat) "
                    "instead of the temperature Blender makes from the flame grid")
    fluid_velocity: bpy.props.EnumProperty(
        name='Fluid velocity', default='blender',
        items=[('blender', 'As Blender renders it',
                "A domain's cache velocity read as Cycles reads it"),
               ('physical', 'As simulated',
                "A domain's cache velocity moving the smoke as the simulation did")],
        description="How a smoke domain's velocity blurs it when motion blur is on")

    def execute(self, context):
        msgs = []
        try:
            ex = export_scene(self.filepath, context.scene, context.view_layer,
                              warn=lambda kind, m: msgs.append((kind, m)),
                              frames=self.frames or None, output=self.output or None,
                              cache_temperature=self.cache_temperature,
                              fluid_velocity=self.fluid_velocity)
        except ExportError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, internal_error(e))
            return {'CANCELLED'}
        for kind, m in msgs:
            self.report({'WARNING'} if kind == 'warning' else {'INFO'}, m)
            print(f'{PREFIX}: {kind}: {m}', file=sys.stderr)
        self.report({'INFO'}, f'Exported {self.filepath} ({len(ex.warnings)} warnings)')
        return {'FINISHED'}


def menu_func_export(self, context):
    self.layout.operator(EXPORT_SCENE_OT_vdbphoton.bl_idname, text='vdbphoton scene (.toml)')


# ------------------------------------------------------------ render engine
#
# vdbphoton as a render engine of Blender: F12 exports the current frame
# with the exporter above into a temporary folder, runs the `vdbphoton`
# binary on it with `--progress json`, follows its progress, draws each
# checkpoint into the render result, stops it on Esc, and loads the finished
# EXR (beauty as Combined, the AOVs as render passes).

# The binary's version this add-on speaks to (`vdbphoton --version`): the
# same major and minor.
BINARY_VERSION = (0, 2)

# Render passes from the EXR's layers: (pass name, channels, Blender's
# channel ids, EXR layer).
AOV_PASSES = [('Direct', 3, 'RGB', 'direct'), ('Indirect', 3, 'RGB', 'indirect'),
              ('Emission', 3, 'RGB', 'emission'), ('Transmittance', 1, 'X', 'transmittance')]
DENOISE_PASSES = [('Noisy Image', 4, 'RGBA', 'noisy'), ('Denoising Albedo', 3, 'RGB', 'albedo')]
# Cycles' Shadow Catcher pass (its add-on's engine.py names it so): the EXR's
# layer `shadow_catcher`, 1 where no catcher is seen; composite = Combined
# over (background x Shadow Catcher).
CATCHER_PASS = ('Shadow Catcher', 3, 'RGB', 'shadow_catcher')


def scene_has_shadow_catcher(scene):
    """Whether an object of `scene`, or of a collection its objects
    instance, is a shadow catcher (Object > Visibility > Mask)."""
    seen = set()

    def walk(objects):
        for o in objects:
            # (A light's flag reads True in Blender 5.0.1; only geometry and
            # instancers count.)
            if o.type in SURFACE_TYPES + ('EMPTY',) and getattr(o, 'is_shadow_catcher', False):
                return True
            c = o.instance_collection if o.instance_type == 'COLLECTION' else None
            if c is not None and c.name_full not in seen:
                seen.add(c.name_full)
                if walk(c.all_objects):
                    return True
        return False

    return walk(scene.objects)


def wants_shadow_catcher(scene, view_layer):
    """The Shadow Catcher pass is registered as Cycles registers it, when
    the view layer asks for it (View Layer Properties > Passes > Shadow
    Catcher), and whenever the scene has a shadow catcher."""
    cy = getattr(view_layer, 'cycles', None) if view_layer is not None else None
    if cy is not None and getattr(cy, 'use_pass_shadow_catcher', False):
        return True
    return scene is not None and scene_has_shadow_catcher(scene)


def engine_passes(scene, view_layer, denoise):
    """The passes beside Combined, as update_render_passes registers them."""
    return AOV_PASSES + (DENOISE_PASSES if denoise else []) + \
        ([CATCHER_PASS] if wants_shadow_catcher(scene, view_layer) else [])


def read_exr_channels(path):
    """The channels of a scan-line EXR as vdbphoton writes it (single part,
    ZIP, ZIPS or no compression), float32 arrays of shape (height, width),
    top row first, and the display size."""
    import numpy as np
    import zlib
    with open(path, 'rb') as f:
        data = f.read()
    if data[:4] != b'\x76\x2f\x31\x01':
        raise ExportError(f'{path}: not an OpenEXR file')
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b'\0', pos)
        name = data[pos:end].decode()
        end2 = data.index(b'\0', end + 1)
        size = struct.unpack_from('<i', data, end2 + 1)[0]
        attrs[name] = data[end2 + 5:end2 + 5 + size]
        pos = end2 + 5 + size
    pos += 1
    chans, raw, p = [], attrs['channels'], 0
    while raw[p] != 0:
        end = raw.index(b'\0', p)
        chans.append((raw[p:end].decode(), struct.unpack_from('<i', raw, end + 1)[0]))
        p = end + 17
    x0, y0, x1, y1 = struct.unpack('<iiii', attrs['dataWindow'])
    dx0, dy0, dx1, dy1 = struct.unpack('<iiii', attrs['displayWindow'])
    comp = attrs['compression'][0]
    lines = {0: 1, 2: 1, 3: 16}.get(comp)
    if lines is None:
        raise ExportError(f'{path}: EXR compression {comp} is not one vdbphoton writes')
    w, h = x1 - x0 + 1, y1 - y0 + 1
    size = {0: 4, 1: 2, 2: 4}
    dtype = {0: '<u4', 1: '<f2', 2: '<f4'}
    out = {n: np.zeros((h, w), dtype=np.float32) for n, _ in chans}
    nblocks = (h + lines - 1) // lines
    for off in struct.unpack_from(f'<{nblocks}Q', data, pos):
        y, n = struct.unpack_from('<ii', data, off)
        block = data[off + 8:off + 8 + n]
        nl = min(lines, y1 - y + 1)
        if comp != 0 and n < nl * w * sum(size[t] for _, t in chans):
            b = np.frombuffer(zlib.decompress(block), dtype=np.uint8).astype(np.int32)
            b = (np.cumsum(np.concatenate(([b[0]], b[1:] - 128))) & 0xFF).astype(np.uint8)
            half = (len(b) + 1) // 2
            t = np.empty(len(b), dtype=np.uint8)
            t[0::2] = b[:half]
            t[1::2] = b[half:]
            block = t.tobytes()
        q = 0
        for line in range(nl):
            for name, t in chans:
                nb = w * size[t]
                out[name][y - y0 + line] = np.frombuffer(block[q:q + nb], dtype=dtype[t])
                q += nb
    return out, (x0 - dx0, y0 - dy0), (dx1 - dx0 + 1, dy1 - dy0 + 1)


def find_binary():
    """The vdbphoton binary: the add-on's preference, else $VDBPHOTON, else
    `vdbphoton` on PATH."""
    import shutil
    exe = ''
    addon = bpy.context.preferences.addons.get(__name__)
    if addon is not None and getattr(addon.preferences, 'binary', ''):
        exe = bpy.path.abspath(addon.preferences.binary)
    exe = exe or os.environ.get('VDBPHOTON', '') or (shutil.which('vdbphoton') or '')
    if not exe:
        raise ExportError("the vdbphoton binary was not found: set its path in the add-on's "
                          "preferences (Edit > Preferences > Add-ons > vdbphoton) or put it on PATH")
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        raise ExportError(f"the vdbphoton binary '{exe}' is not an executable file")
    return exe


def check_binary(exe):
    """Checks that `exe` is a vdbphoton of the version this add-on speaks to
    (`vdbphoton --version`); returns its version text."""
    import subprocess
    try:
        out = subprocess.run([exe, '--version'], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError) as e:
        raise ExportError(f"cannot run the vdbphoton binary '{exe}': {e}") from None
    m = re.match(r'vdbphoton (\d+)\.(\d+)\.(\d+)', out.stdout.strip())
    if out.returncode != 0 or not m:
        said = ((out.stdout or out.stderr).strip().splitlines() or [''])[0][:80]
        raise ExportError(f"'{exe}' is not a vdbphoton binary (its --version said {said!r})")
    if (int(m.group(1)), int(m.group(2))) != BINARY_VERSION:
        raise ExportError(f"'{exe}' is vdbphoton {m.group(0)[10:]}; this add-on "
                          f"({'.'.join(map(str, bl_info['version']))}) needs vdbphoton "
                          f"{BINARY_VERSION[0]}.{BINARY_VERSION[1]}.x")
    return m.group(0)


def engine_command(exe, scene_file, exr, frame, s):
    """The command line the engine runs for settings `s` (the scene's
    VdbphotonSettings)."""
    args = [exe, 'render', scene_file, '--frame', str(frame), '-o', exr, '--no-preview',
            '--progress', 'json', '--addon-version', '.'.join(map(str, bl_info['version'])),
            '--aovs', '--integrator', s.integrator,
            '--seed', str(s.seed), '--checkpoint', f'{s.checkpoint:g}s', '--no-resume-state']
    if s.budget == 'TIME':
        args += ['--time', f'{s.time_limit:g}s']
    else:
        args += ['--spp', str(s.samples)]
    if s.max_bounces > 0:
        args += ['--max-bounces', str(s.max_bounces)]
    if s.threads > 0:
        args += ['--threads', str(s.threads)]
    if s.denoise:
        args.append('--denoise')
    return args


class VDBPHOTON_AddonPreferences(bpy.types.AddonPreferences):
    bl_idname = __name__
    binary: bpy.props.StringProperty(
        name='vdbphoton binary', subtype='FILE_PATH', default='',
        description='The vdbphoton program (empty: $VDBPHOTON, else vdbphoton on PATH)')

    def draw(self, context):
        self.layout.prop(self, 'binary')


class VdbphotonSettings(bpy.types.PropertyGroup):
    integrator: bpy.props.EnumProperty(
        name='Integrator', default='auto',
        items=[('auto', 'Auto', 'Photon mapping for thick volumes, the path tracer for thin '
                'ones and for denoised images'),
               ('photon', 'Photon Mapping', 'Volumetric photon mapping (progressive)'),
               ('path', 'Path Tracing', 'The reference volumetric path tracer')])
    budget: bpy.props.EnumProperty(
        name='Budget', default='SAMPLES',
        items=[('SAMPLES', 'Samples', 'Render a number of samples per pixel'),
               ('TIME', 'Time', 'Render for a wall-clock time')])
    samples: bpy.props.IntProperty(name='Samples', default=64, min=1, max=1 << 24)
    time_limit: bpy.props.FloatProperty(name='Time Limit', default=30.0, min=0.1,
                                        max=1e7, unit='TIME_ABSOLUTE')
    max_bounces: bpy.props.IntProperty(
        name='Max Bounces', default=0, min=0, max=100000,
        description="Scattering events at most along a path (0: from Cycles' Volume and "
                    "Total bounces, as the exporter writes them)")
    seed: bpy.props.IntProperty(name='Seed', default=0, min=0)
    threads: bpy.props.IntProperty(name='Threads', default=0, min=0, max=1024,
                                   description='Worker threads (0: all cores)')
    denoise: bpy.props.BoolProperty(name='Denoise', default=False,
                                    description='Denoise with Open Image Denoise')
    checkpoint: bpy.props.FloatProperty(
        name='Update Interval', default=5.0, min=0.1, max=3600.0, unit='TIME_ABSOLUTE',
        description='How often the image in Blender is updated while rendering (each '
                    'update writes an image: about 0.5 s at 1920 x 1080)')


class VdbphotonRenderEngine(bpy.types.RenderEngine):
    bl_idname = 'VDBPHOTON'
    bl_label = 'vdbphoton'
    bl_use_preview = False
    bl_use_postprocess = True

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, 'Combined', 4, 'RGBA', 'COLOR')
        denoise = scene is not None and scene.vdbphoton.denoise
        for name, n, chan, _ in engine_passes(scene, renderlayer, denoise):
            self.register_pass(scene, renderlayer, name, n, chan,
                               'VALUE' if n == 1 else 'COLOR')

    def render(self, depsgraph):
        import tempfile
        import shutil
        scene = depsgraph.scene
        try:
            exe = find_binary()
            check_binary(exe)
        except ExportError as e:
            self.report({'ERROR'}, f'vdbphoton: {e}')
            return
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, f'vdbphoton: {internal_error(e)}')
            return
        try:
            tmp = tempfile.mkdtemp(prefix='vdbphoton-render-')
        except OSError as e:
            self.report({'ERROR'}, f'vdbphoton: cannot make a temporary folder: {e}')
            return
        try:
            self._render(depsgraph, scene, exe, tmp)
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, f'vdbphoton: {internal_error(e)}')
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def _render(self, depsgraph, scene, exe, tmp):
        import queue
        import subprocess
        import threading
        s = scene.vdbphoton
        r = scene.render
        w = r.resolution_x * r.resolution_percentage // 100
        h = r.resolution_y * r.resolution_percentage // 100
        frame = scene.frame_current
        layer = depsgraph.view_layer.name
        scene_file = os.path.join(tmp, 'scene.toml')
        exr = os.path.join(tmp, 'frame.exr')
        msgs = []
        try:
            export_scene(scene_file, scene, depsgraph.view_layer,
                         warn=lambda kind, m: msgs.append((kind, m)),
                         frames=str(frame), output=exr, no_preview=True, depsgraph=depsgraph)
        except ExportError as e:
            self.report({'ERROR'}, f'vdbphoton: {e}')
            return
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, f'vdbphoton: {internal_error(e)}')
            return
        for kind, m in msgs:
            # The engine renders a border itself (--region).
            if kind == 'warning' and 'render region (border)' not in m:
                self.report({'WARNING'}, f'vdbphoton: {m}')
        # The passes update_render_passes registered, in this view layer's
        # result (Blender calls render() once per view layer).
        passes = engine_passes(scene, depsgraph.view_layer, s.denoise)
        result = self.begin_result(0, 0, w, h, layer=layer)
        args = engine_command(exe, scene_file, exr, frame, s)
        if r.use_border:
            # Blender's result is the border (as its pipeline cuts it:
            # truncated fractions of the image, y from the bottom); render
            # just those pixels (--region, y from the top).
            x0, x1 = int(r.border_min_x * w), int(r.border_max_x * w)
            y0, y1 = int(r.border_min_y * h), int(r.border_max_y * h)
            args += ['--region', f'{x0},{h - y1},{x1},{h - y0}']
        self.update_stats('', f'vdbphoton: frame {frame}, starting')
        proc = None
        try:
            try:
                proc = subprocess.Popen(args, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.PIPE, text=True,
                                        encoding='utf-8', errors='replace', bufsize=1)
            except OSError as e:
                self.report({'ERROR'}, f"vdbphoton: cannot run '{exe}': {e}")
                return
            lines = queue.Queue()

            def pump():
                try:
                    for line in proc.stderr:
                        lines.put(line)
                finally:
                    lines.put(None)

            threading.Thread(target=pump, daemon=True).start()
            errors = []
            while True:
                try:
                    line = lines.get(timeout=0.05)
                except queue.Empty:
                    line = ''
                if line is None:
                    break
                if line:
                    self._event(line, result, passes, errors)
                if self.stop_requested():
                    # Esc: stop the render (the `finally` below). The last
                    # checkpoint drawn stays in the image.
                    self.update_stats('', 'vdbphoton: cancelled')
                    return
            rc = proc.wait()
            if rc != 0:
                # The first error names the file or setting; later ones
                # sum up.
                self.report({'ERROR'}, errors[0] if errors else
                            f'vdbphoton: the render failed (exit code {rc})')
                return
            try:
                self._load(exr, result, passes)
            except Exception as e:  # noqa: BLE001 (any unreadable image is one report)
                self.report({'ERROR'}, f'vdbphoton: cannot read the rendered image: {e}')
                return
            self.update_progress(1.0)
        finally:
            # Whatever happened: the process ends (SIGTERM, killed after a
            # second) and the result is handed back once.
            if proc is not None and proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=1.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
            self.end_result(result)

    # Blender's side of the render, as methods of ours so that a test can
    # watch them (Blender's own, `test_break`, `update_progress`, ..., are
    # RNA functions that Python cannot replace).

    def stop_requested(self):
        """Whether Blender asked to stop (Esc): `test_break`."""
        return self.test_break()

    def show_progress(self, fraction, text):
        """The progress bar and the status line."""
        self.update_progress(fraction)
        self.update_stats('', text)

    def show_checkpoint(self, result, passes):
        """A checkpoint of `passes` passes, loaded into `result`, drawn."""
        self.update_result(result)

    def _event(self, line, result, passes, errors):
        import json
        line = line.strip()
        if not line.startswith('{'):
            # Errors, and the command line's own complaints (an option this
            # binary does not know), are `vdbphoton: ...` lines.
            if line.startswith('vdbphoton: ') and not line.startswith('vdbphoton: warning:'):
                errors.append(line)
            return
        try:
            e = json.loads(line)
        except ValueError:
            return
        kind = e.get('event')
        if kind == 'progress':
            eta = e.get('eta')
            self.show_progress(min(1.0, max(0.0, float(e.get('fraction', 0.0)))),
                               f"vdbphoton: pass {e.get('passes', 0) + 1}, "
                               f"{e.get('elapsed', 0.0):.0f} s"
                               + (f', ETA {eta:.0f} s' if eta is not None else ''))
        elif kind == 'checkpoint':
            try:
                self._load(e['path'], result, passes)
            except Exception:  # noqa: BLE001 (a checkpoint not drawn is no error)
                return
            self.show_checkpoint(result, int(e.get('passes', 0)))
        elif kind == 'warning':
            self.report({'WARNING'}, f"vdbphoton: {e.get('message', '')}")

    def _load(self, path, result, passes):
        """The EXR at `path` into the render result's passes."""
        import numpy as np
        ch, _, _ = read_exr_channels(path)
        layer = result.layers[0]
        rw, rh = result.resolution_x, result.resolution_y
        dh, dw = ch['R'].shape
        if (dw, dh) != (rw, rh):
            raise ExportError(f'{path}: {dw} x {dh} pixels, the render is {rw} x {rh}')

        def put(pass_name, names):
            px = np.stack([ch[n] for n in names], axis=-1)[::-1]
            layer.passes[pass_name].rect.foreach_set(np.ascontiguousarray(px, np.float32).ravel())

        put('Combined', ['R', 'G', 'B', 'A'])
        for name, n, chan, exr_layer in passes:
            names = [f'{exr_layer}.{c}' for c in ('RGBA'[:n] if n > 1 else 'Y')]
            if all(x in ch for x in names):
                put(name, names)
            elif exr_layer == 'shadow_catcher':
                # No catcher in the render: 1 everywhere, Cycles' value
                # where no catcher is seen.
                layer.passes[name].rect.foreach_set(np.ones(rw * rh * n, dtype=np.float32))


class RENDER_PT_vdbphoton(bpy.types.Panel):
    bl_label = 'vdbphoton'
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = 'render'
    COMPAT_ENGINES = {'VDBPHOTON'}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        s = context.scene.vdbphoton
        col = self.layout.column()
        col.use_property_split = True
        col.prop(s, 'integrator')
        col.prop(s, 'budget')
        col.prop(s, 'samples' if s.budget == 'SAMPLES' else 'time_limit')
        col.prop(s, 'max_bounces')
        col.prop(s, 'seed')
        col.prop(s, 'threads')
        col.prop(s, 'denoise')
        col.prop(s, 'checkpoint')


def compatible_panels():
    """Blender's own panels that also serve this engine: those of the output,
    format, frame range, colour management, camera and light, which list
    Blender's built-in engines."""
    for name in dir(bpy.types):
        panel = getattr(bpy.types, name, None)
        engines = getattr(panel, 'COMPAT_ENGINES', None)
        if isinstance(engines, set) and 'BLENDER_RENDER' in engines and \
                (name.startswith(('RENDER_PT_', 'DATA_PT_', 'WORLD_PT_'))):
            yield panel


ENGINE_CLASSES = (VDBPHOTON_AddonPreferences, VdbphotonSettings, VdbphotonRenderEngine,
                  RENDER_PT_vdbphoton)


def register():
    bpy.utils.register_class(EXPORT_SCENE_OT_vdbphoton)
    bpy.types.TOPBAR_MT_file_export.append(menu_func_export)
    for c in ENGINE_CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.vdbphoton = bpy.props.PointerProperty(type=VdbphotonSettings)
    for p in compatible_panels():
        p.COMPAT_ENGINES.add('VDBPHOTON')


def unregister():
    for p in compatible_panels():
        p.COMPAT_ENGINES.discard('VDBPHOTON')
    del bpy.types.Scene.vdbphoton
    for c in reversed(ENGINE_CLASSES):
        bpy.utils.unregister_class(c)
    bpy.types.TOPBAR_MT_file_export.remove(menu_func_export)
    bpy.utils.unregister_class(EXPORT_SCENE_OT_vdbphoton)


# ------------------------------------------------------------- command line

USAGE = ("usage: blender -b FILE.blend -P vdbphoton_export.py -- OUT.toml [options]\n"
         "       python vdbphoton_export.py FILE.blend OUT.toml [options]\n"
         "options: --frames A-B  --output PATH.exr  --preview PATH.png  --no-preview\n"
         "         --scene NAME  --cache-temperature  --fluid-velocity blender|physical")


def main(argv):
    import argparse
    ap = argparse.ArgumentParser(prog='vdbphoton_export.py', usage=USAGE, add_help=True)
    ap.add_argument('paths', nargs='+')
    ap.add_argument('--frames')
    ap.add_argument('--output')
    ap.add_argument('--preview')
    ap.add_argument('--no-preview', action='store_true')
    ap.add_argument('--scene')
    ap.add_argument('--cache-temperature', action='store_true')
    ap.add_argument('--fluid-velocity', choices=['blender', 'physical'], default='blender')
    try:
        a = ap.parse_args(argv)
    except SystemExit as e:
        return 2 if e.code else 0
    paths = a.paths
    if len(paths) == 2 and paths[0].endswith('.blend'):
        blend, out = paths
        try:
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend), load_ui=False)
        except Exception as e:  # noqa: BLE001
            print(f'{PREFIX}: error: cannot open {blend}: {str(e).strip().splitlines()[-1]}',
                  file=sys.stderr)
            return 1
    elif len(paths) == 1:
        out = paths[0]
        if not bpy.data.filepath:
            print(f'{PREFIX}: error: no .blend file is open (give FILE.blend OUT.toml)',
                  file=sys.stderr)
            return 2
    else:
        print(USAGE, file=sys.stderr)
        return 2
    scene = bpy.data.scenes.get(a.scene) if a.scene else bpy.context.scene
    if scene is None:
        print(f"{PREFIX}: error: no scene '{a.scene}' (scenes: "
              f"{', '.join(s.name for s in bpy.data.scenes)})", file=sys.stderr)
        return 1

    def warn(kind, m):
        print(f'{PREFIX}: {kind}: {m}', file=sys.stderr, flush=True)

    try:
        ex = export_scene(out, scene, None, warn=warn, frames=a.frames,
                          output=a.output, preview=a.preview, no_preview=a.no_preview,
                          cache_temperature=a.cache_temperature,
                          fluid_velocity=a.fluid_velocity)
    except ExportError as e:
        print(f'{PREFIX}: error: {e}', file=sys.stderr)
        return 1
    print(f"{PREFIX}: wrote {os.path.abspath(out)} ({len(ex.warnings)} warnings)")
    return 0


def _cli_args():
    """Arguments after '--' (blender -P), else after the script (python)."""
    if '--' in sys.argv:
        return sys.argv[sys.argv.index('--') + 1:]
    if bpy.app.background and os.path.basename(sys.argv[0]).startswith('blender'):
        return []
    return sys.argv[1:]


def run_main():
    """main(), never a traceback: an unexpected exception is one error line
    and exit status 1."""
    try:
        return main(_cli_args())
    except Exception as e:  # noqa: BLE001
        print(f'{PREFIX}: error: {internal_error(e)}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    code = run_main()
    sys.stdout.flush()
    sys.stderr.flush()
    if os.path.basename(sys.argv[0]).lower().startswith('blender'):
        sys.exit(code)
    # The bpy module: exit at once (Mantaflow objects of an opened .blend can
    # abort in their destructors at interpreter exit).
    os._exit(code)
