"""The vdbphoton exporter's command line; the add-on itself is the package
beside this file, tools/blender/vdbphoton/ (installed as a Blender extension
built by tools/blender/build_extension.py).

    blender -b FILE.blend -P tools/blender/vdbphoton_export.py -- OUT.toml \\
        [--frames A-B] [--output 'renders/frame_{frame:04}.exr'] [--preview P.png | --no-preview]
        [--scene NAME] [--cache-temperature] [--fluid-velocity blender|physical]
    VENV/bin/python tools/blender/vdbphoton_export.py FILE.blend OUT.toml [same options]

VENV is a Python 3.11 venv with `pip install bpy==5.0.1`. What is exported
is in vdbphoton/export.py's docstring and tools/blender/README.md.

Imported as a module (`import vdbphoton_export` with tools/blender on
sys.path, as the test scripts do), it is the package: every name of its
modules (export_scene, Exporter, register, VdbphotonRenderEngine, ...) is
an attribute of this module, the same object as the package's.
"""

import os
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

import vdbphoton  # noqa: E402  (tools/blender/vdbphoton/)
from vdbphoton import (binary, cli, engine, export, meshes, properties,  # noqa: E402
                       scenefile, surfaces, ui, util, volume_materials)

_MODULES = (vdbphoton, export, util, scenefile, volume_materials, surfaces, meshes, binary,
            engine, properties, ui, cli)


def __getattr__(name):
    """The package's names, looked up in its modules (PEP 562)."""
    for m in _MODULES:
        if name in vars(m):
            return vars(m)[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def register():
    vdbphoton.register()


def unregister():
    vdbphoton.unregister()


if __name__ == '__main__':
    code = cli.run_main()
    sys.stdout.flush()
    sys.stderr.flush()
    if os.path.basename(sys.argv[0]).lower().startswith('blender'):
        sys.exit(code)
    # The bpy module: exit at once (Mantaflow objects of an opened .blend can
    # abort in their destructors at interpreter exit).
    os._exit(code)
