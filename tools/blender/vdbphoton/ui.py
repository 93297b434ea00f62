"""What the artist sees: File > Export > vdbphoton scene (.toml), and the
vdbphoton panel in Render Properties (with Blender's own panels that serve
this engine too)."""

import sys

import bpy

from .export import export_scene
from .util import PREFIX, ExportError, internal_error

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
