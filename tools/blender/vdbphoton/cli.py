"""The exporter's command line, which tools/blender/vdbphoton_export.py
runs:

    blender -b FILE.blend -P tools/blender/vdbphoton_export.py -- OUT.toml \\
        [--frames A-B] [--output 'renders/frame_{frame:04}.exr'] [--preview P.png | --no-preview]
        [--scene NAME] [--cache-temperature] [--fluid-velocity blender|physical]
    VENV/bin/python tools/blender/vdbphoton_export.py FILE.blend OUT.toml [same options]

VENV is a Python 3.11 venv with `pip install bpy==5.0.1`. Warnings and
errors are `vdbphoton_export: warning: ...` lines on stderr; exit status 1
for a failed export, 2 for a bad command line."""

import os
import sys

import bpy

from .export import export_scene
from .util import PREFIX, ExportError, internal_error

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
