"""Surface materials as Cycles shades them: a mesh's material read into
its [mesh.material] table (SurfaceReader), with the nearest supported
shading and one warning for what vdbphoton cannot render."""

import math
import os

import bpy

from .util import g7, rgb3, rounded, uses_nodes

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
