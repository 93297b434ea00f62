"""The scene exporter: a Blender scene as a vdbphoton scene file (TOML),
its meshes as PLY files beside it (export_scene, the Exporter). Run by the
render engine (engine.py), File > Export (ui.py) and the command line
(cli.py, through tools/blender/vdbphoton_export.py).

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

import math
import os
import re
import time

import bpy
from mathutils import Matrix, Vector

from .meshes import (CURVE_TYPES, MAX_MERGED_TRIANGLES, MAX_MESH_ENTRIES, OBJECT_KINDS,
                     RAY_VISIBILITY, SURFACE_TYPES, VISIBILITY_KEYS, is_animated,
                     is_fluid_domain, merge_world, read_mesh_arrays, slot_materials,
                     split_corners, write_ply)
from .scenefile import to_toml, write_scene
from .surfaces import (BLACK_SURFACE, TEXTURE_EXTENSIONS, SurfaceReader, TextureRef,
                       material_key, upstream)
from .util import (FRAMES_RE, UNSET, ExportError, compress_frames, expand_frames, f32,
                   frame_range_text, g7, internal_error, matrix_rows, pattern_path, rgb3,
                   rounded, sequence_pattern, uses_nodes)
from .volume_materials import (SCATTER_PHASES, Attr, DefaultPrincipledVolume,
                               MaterialContext, phase_label)

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


def invisible_to_rays(o):
    """Cycles renders nothing of an object whose ray visibilities are all
    off (Blender 3.0+: Object > Visibility > Ray Visibility)."""
    return all(hasattr(o, k) and not getattr(o, k) for k in RAY_VISIBILITY)


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
