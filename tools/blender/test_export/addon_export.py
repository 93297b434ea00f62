"""The exporter as an add-on: register it in Blender (bpy module), check
its entry in File > Export, export FILE.blend through the operator to
OUT.toml, unregister. Prints ADDON_OK when all of it worked.

    VENV/bin/python tools/blender/test_export/addon_export.py FILE.blend OUT.toml
"""
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import vdbphoton_export  # noqa: E402  (tools/blender/vdbphoton_export.py)



def check(blend, out):
    bpy.ops.wm.open_mainfile(filepath=blend)
    vdbphoton_export.register()
    try:
        # The File > Export menu draws the add-on's entry.
        draw = bpy.types.TOPBAR_MT_file_export._dyn_ui_initialize()
        assert vdbphoton_export.menu_func_export in draw, "no entry in File > Export"
        assert hasattr(bpy.ops.export_scene, 'vdbphoton'), "operator not registered"
        result = bpy.ops.export_scene.vdbphoton(filepath=out)
        assert result == {'FINISHED'}, result
        assert os.path.isfile(out), f"{out} not written"
    finally:
        vdbphoton_export.unregister()
    assert not hasattr(bpy.types, 'EXPORT_SCENE_OT_vdbphoton'), "still registered"


try:
    check(sys.argv[1], sys.argv[2])
except Exception as e:  # noqa: BLE001 (any failure fails the test)
    print(f'addon_export: {type(e).__name__}: {e}', file=sys.stderr, flush=True)
    os._exit(1)
print('ADDON_OK', flush=True)
# As vdbphoton_export.py does: leave without the bpy module's teardown, which
# aborts in Mantaflow's grid cache once a .blend with a fluid domain was
# opened (a problem of the pip wheel, not of the exporter).
os._exit(0)
