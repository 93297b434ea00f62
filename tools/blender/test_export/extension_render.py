"""The vdbphoton extension installed into Blender (bpy module) through
Blender's extension API and rendering with F12 with the binary it holds.
Prints one line `EXTENSION {json}` with what it found; the test in
tests/blender_export.rs checks it.

    BLENDER_USER_RESOURCES=DIR VENV/bin/python \
        tools/blender/test_export/extension_render.py ZIP CLOUD.vdb OUT_DIR

BLENDER_USER_RESOURCES (required: the user repository goes there, never
into ~) holds Blender's user extensions. What it does:
  - validates ZIP with Blender's own checker (`blender --command extension
    validate`: bl_pkg's blender_ext.py) and installs it into the
    `user_default` repository with bpy.ops.extensions.package_install_files,
    enabled on install;
  - with a scene built before (camera, sun, a Volume object of CLOUD.vdb
    with a Principled Volume of density 20, 48 x 36), selects the engine and
    renders with F12 into OUT_DIR/f12.exr (multilayer: the passes);
  - exports the scene as the engine does (OUT_DIR/scene.toml) and writes
    the engine's command line for it (which the test runs: the same bits);
  - removes the bundled binary: F12 is then one error in Blender's report;
  - checks a stand-in binary whose shared libraries are missing;
  - disables the add-on.
The binary must come from the extension: the test clears VDBPHOTON and
PATH of any vdbphoton, and the script records that neither is there.
"""
import json
import os
import shutil
import subprocess
import sys

import bpy

import addon_utils  # noqa: E402  (Blender's; on sys.path once bpy is imported)

MODULE = 'bl_ext.user_default.vdbphoton'


def validate(zip_path):
    """Blender's own manifest checker on the zip (strict, as the extensions
    platform checks it)."""
    cli = os.path.join(bpy.utils.system_resource('SCRIPTS'), 'addons_core', 'bl_pkg', 'cli',
                       'blender_ext.py')
    r = subprocess.run([sys.executable, cli, 'validate', zip_path],
                       capture_output=True, text=True)
    return {'status': r.returncode, 'output': (r.stdout + r.stderr).strip()}


def build(vdb):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    r = sc.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 48, 36, 100
    sc.frame_start, sc.frame_end, sc.frame_current = 1, 1, 1
    cam = bpy.data.objects.new('Camera', bpy.data.cameras.new('Camera'))
    cam.location = (0.0, -4.0, 0.5)
    cam.rotation_euler = (1.45, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sun = bpy.data.objects.new('Sun', bpy.data.lights.new('Sun', 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.2, 0.0)
    sc.collection.objects.link(sun)
    vol = bpy.data.volumes.new('Cloud')
    vol.filepath = vdb
    obj = bpy.data.objects.new('Cloud', vol)
    sc.collection.objects.link(obj)
    mat = bpy.data.materials.new('Smoke')
    if not mat.node_tree:
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    pv.inputs['Density'].default_value = 20.0
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(pv.outputs['Volume'], out.inputs['Volume'])
    vol.materials.append(mat)
    if hasattr(r.image_settings, 'media_type'):  # Blender 5
        r.image_settings.media_type = 'MULTI_LAYER_IMAGE'
    r.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    r.image_settings.color_depth = '32'
    r.use_compositing = False
    r.image_settings.exr_codec = 'ZIP'
    return sc


def use_engine(sc):
    """vdbphoton's engine and settings (the add-on's, once it is enabled)."""
    sc.render.engine = 'VDBPHOTON'
    s = sc.vdbphoton
    s.integrator = 'path'
    s.samples = 16
    s.seed = 3


def f12(sc, path, found, key):
    """F12 into `path`; Blender's error report (an exception of the
    operator in a script), or None, in found[key]."""
    sc.render.filepath = path
    try:
        bpy.ops.render.render(write_still=True)
        found[key] = None
    except RuntimeError as e:
        found[key] = str(e)


def main(zip_path, vdb, out_dir):
    found = {}
    home = os.environ.get('BLENDER_USER_RESOURCES')
    if not home or not os.path.isdir(home):
        raise RuntimeError('set BLENDER_USER_RESOURCES to a folder (the extension goes there)')
    found['vdbphoton_on_path'] = shutil.which('vdbphoton')
    found['VDBPHOTON'] = os.environ.get('VDBPHOTON')
    found['validate'] = validate(zip_path)
    # The zip's files and their Unix modes, as build_extension.py wrote them.
    import zipfile
    with zipfile.ZipFile(zip_path) as zf:
        found['zip'] = {i.filename: i.external_attr >> 16 for i in zf.infolist()}
    # The scene first: factory settings would also reset the add-ons.
    sc = build(vdb)

    repo = next(r for r in bpy.context.preferences.extensions.repos if r.module == 'user_default')
    found['repo_inside_user_resources'] = os.path.realpath(repo.directory).startswith(
        os.path.realpath(home) + os.sep)
    found['install'] = sorted(bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo='user_default', enable_on_install=True))
    found['enabled'] = MODULE in bpy.context.preferences.addons
    pkg = sys.modules.get(MODULE)
    installed = os.path.dirname(pkg.__file__) if pkg else ''
    found['installed_in_repo'] = os.path.dirname(installed) == os.path.realpath(repo.directory) \
        or os.path.dirname(installed) == repo.directory
    bundled = os.path.join(installed, 'bin', 'vdbphoton')
    found['bundled'] = bundled
    found['bundled_executable_before'] = os.access(bundled, os.X_OK)
    found['files'] = sorted(os.path.relpath(os.path.join(d, f), installed)
                            for d, _, fs in os.walk(installed) for f in fs
                            if '__pycache__' not in d)

    use_engine(sc)
    f12(sc, os.path.join(out_dir, 'f12.exr'), found, 'error')
    found['saved'] = os.path.isfile(os.path.join(out_dir, 'f12.exr'))
    found['bundled_executable_after'] = os.access(bundled, os.X_OK)
    # The binary the engine used: the one inside the extension.
    found['found_binary'] = sys.modules[MODULE + '.binary'].find_binary()

    # The scene as the engine exports it, and its command line.
    export = sys.modules[MODULE + '.export']
    engine = sys.modules[MODULE + '.engine']
    toml = os.path.join(out_dir, 'scene.toml')
    export.export_scene(toml, sc, frames=str(sc.frame_current),
                        output=os.path.join(out_dir, 'cli.exr'), no_preview=True)
    found['command'] = engine.engine_command(found['found_binary'], toml,
                                             os.path.join(out_dir, 'cli.exr'),
                                             sc.frame_current, sc.vdbphoton)

    # Without its binary (and none elsewhere): one error naming where the
    # extension holds it; Blender goes on.
    hidden = bundled + '.hidden'
    os.rename(bundled, hidden)
    try:
        f12(sc, os.path.join(out_dir, 'none.exr'), found, 'missing_error')
    finally:
        os.rename(hidden, bundled)

    # A binary whose libraries are missing (the dynamic loader's message, as
    # glibc words it, from a stand-in): one error naming the library and
    # the Debian package.
    fake = os.path.join(out_dir, 'nolibs')
    with open(fake, 'w') as f:
        f.write('#!/bin/sh\necho "$0: error while loading shared libraries: libopenvdb.so.10.0: '
                'cannot open shared object file: No such file or directory" >&2\nexit 127\n')
    os.chmod(fake, 0o755)
    try:
        sys.modules[MODULE + '.binary'].check_binary(fake)
        found['no_libs_error'] = None
    except Exception as e:  # noqa: BLE001 (the test reads the message)
        found['no_libs_error'] = str(e)

    # Disabled (Blender runs the package's unregister): nothing of it left.
    errors = []
    addon_utils.disable(MODULE, default_set=True, handle_error=lambda e: errors.append(repr(e)))
    found['disable_errors'] = errors
    found['left_after_disable'] = [n for n, left in (
        ('add-on', MODULE in bpy.context.preferences.addons),
        ('Scene.vdbphoton', hasattr(bpy.types.Scene, 'vdbphoton')),
        ('engine', hasattr(bpy.types, 'VdbphotonRenderEngine')),
        ('export operator', hasattr(bpy.types, 'EXPORT_SCENE_OT_vdbphoton'))) if left]
    print('EXTENSION ' + json.dumps(found), flush=True)


try:
    main(*sys.argv[1:4])
except Exception as e:  # noqa: BLE001 (any failure fails the test)
    import traceback
    traceback.print_exc()
    print(f'extension_render: {type(e).__name__}: {e}', file=sys.stderr, flush=True)
    os._exit(1)
# As the other scripts: leave without the bpy module's teardown.
os._exit(0)
