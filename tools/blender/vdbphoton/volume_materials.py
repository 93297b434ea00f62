"""Volume materials: the node graph of a volume's material read into
[volume.material] (MaterialContext: constants, attributes, shader leaves),
and the phase tables of Blender's Volume Scatter."""

import math

from .surfaces import upstream
from .util import g7, rgb3

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
