"""vdbphoton for Blender: a render engine (F12 renders with the vdbphoton
binary, the image and its passes in Blender) and a scene exporter (File >
Export > vdbphoton scene, or the command line, tools/blender/vdbphoton_export.py).

Installed as a Blender extension (4.2 and later: blender_manifest.toml; the
zip that tools/blender/build_extension.py builds holds the binary as
bin/vdbphoton), or as a legacy add-on (bl_info, which extensions ignore).

  export.py            the Blender scene as a vdbphoton scene file (Exporter)
  volume_materials.py  volume materials and Volume Scatter phases
  surfaces.py          surface materials as Cycles shades them
  meshes.py            meshes: which objects, their arrays, PLY files
  scenefile.py         the TOML text, written atomically
  util.py              the error type, numbers, frame lists, file patterns
  binary.py            finding and checking the vdbphoton binary
  engine.py            the render engine
  properties.py        the add-on's preference and the scene's settings
  ui.py                File > Export and the Render Properties panel
  cli.py               the command line
"""

# For the legacy add-on path (Blender 3.4-4.1); an extension's metadata is
# blender_manifest.toml. The version is binary.ADDON_VERSION's.
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

if 'bpy' in locals():
    # Reload Scripts (F8): the modules again, the ones others import first.
    import importlib
    for _m in (util, scenefile, surfaces, volume_materials, meshes, export,  # noqa: F821
               binary, engine, properties, ui, cli):  # noqa: F821
        importlib.reload(_m)

import bpy

from . import util, scenefile, surfaces, volume_materials, meshes, export  # noqa: F401
from . import binary, engine, properties, ui, cli  # noqa: F401
from .engine import VdbphotonRenderEngine
from .properties import VDBPHOTON_AddonPreferences, VdbphotonSettings
from .ui import EXPORT_SCENE_OT_vdbphoton, RENDER_PT_vdbphoton, compatible_panels, menu_func_export


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
