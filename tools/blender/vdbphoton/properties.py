"""The add-on's settings: its preference (the binary's path) and the
scene's render settings shown in the vdbphoton panel (Scene.vdbphoton)."""

import bpy


class VDBPHOTON_AddonPreferences(bpy.types.AddonPreferences):
    # The add-on's module: the package (bl_ext.<repository>.vdbphoton as an
    # extension).
    bl_idname = __package__
    binary: bpy.props.StringProperty(
        name='vdbphoton binary', subtype='FILE_PATH', default='',
        description="The vdbphoton program (empty: $VDBPHOTON, else the one inside the "
                    "extension, else vdbphoton on PATH)")

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
