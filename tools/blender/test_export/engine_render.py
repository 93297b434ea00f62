"""vdbphoton as Blender's render engine, headless (bpy module): builds a
scene (camera, sun, a Volume object of CLOUD.vdb), registers the add-on,
selects the engine and renders through Blender's own operators. Prints one
line `ENGINE {json}` with what it found; tests/blender_engine.rs checks it.

    VENV/bin/python tools/blender/test_export/engine_render.py CLOUD.vdb OUT_DIR CASE

CASE:
  still      F12 with write_still: OUT_DIR/still.exr (multilayer: the
             passes), OUT_DIR/still.toml (the scene exported as the engine
             exports it) and the engine's command line
  denoise    F12 with Denoise: OUT_DIR/denoised.exr (Combined denoised, Noisy
             Image, Denoising Albedo) and the engine's command line
  border     F12 of a cropped border against the whole frame's pixels there
  layers     two view layers, each its own image
  animation  Ctrl-F12 over frames 1-2: OUT_DIR/anim_0001.exr, anim_0002.exr
  nocamera, novolume, missingvdb
             a scene without a camera, without a volume, or whose VDB is
             missing: the error Blender's report gets
  broken     the binary is not vdbphoton (VDBPHOTON points at /bin/true)
  missing    the binary does not exist
  catcherpass  the Shadow Catcher pass registered (or not) as Cycles
             registers it (the view layer's Shadow Catcher pass, or a catcher
             in the scene, also in an instanced collection); F12 with the
             pass asked for and no catcher: OUT_DIR/nocatcher.exr
  catcher    a shadow catcher ground and a holdout ball, film transparent:
             F12 (OUT_DIR/catcher.exr, with the Shadow Catcher pass), the
             scene as exported and the engine's command line
  cancel     Esc (the engine's test_break, through its stop_requested) 1.5 s
             into a long render: how long until the
             engine returned, and whether the process was gone
The binary is $VDBPHOTON.
"""
import json
import os
import sys
import time
from types import SimpleNamespace

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import vdbphoton_export  # noqa: E402


def build(vdb, out_dir):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    r = sc.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 48, 36, 100
    sc.frame_start, sc.frame_end, sc.frame_current = 1, 250, 1
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
    outn = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(pv.outputs['Volume'], outn.inputs['Volume'])
    vol.materials.append(mat)
    vdbphoton_export.register()
    r.engine = 'VDBPHOTON'
    s = sc.vdbphoton
    s.integrator = 'path'
    s.samples = 16
    s.seed = 3
    s.checkpoint = 0.2
    if hasattr(r.image_settings, 'media_type'):  # Blender 5
        r.image_settings.media_type = 'MULTI_LAYER_IMAGE'
    r.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    r.image_settings.color_depth = '32'
    # The file holds the render result's passes (with compositing on,
    # Blender writes the compositor's output: Combined alone).
    r.use_compositing = False
    r.image_settings.exr_codec = 'ZIP'
    return sc


def render_reporting_error(sc, path, found):
    """F12 into `path`; the error Blender's report got in `found['error']`
    (Blender turns an engine's error report into an exception of the
    operator when run from a script), and that Blender went on."""
    sc.render.filepath = path
    try:
        bpy.ops.render.render(write_still=True)
        found['error'] = None
    except RuntimeError as e:
        found['error'] = str(e)
    found['survived'] = True


def main(vdb, out_dir, case):
    sc = build(vdb, out_dir)
    found = {'case': case}
    if case == 'still':
        # Something the renderer does not render: a warning in the report
        # (printed on the console in the background), the render goes on.
        area = bpy.data.objects.new('Softbox', bpy.data.lights.new('Softbox', 'AREA'))
        sc.collection.objects.link(area)
        path = os.path.join(out_dir, 'still.exr')
        sc.render.filepath = path
        # What Blender is shown while it renders: the progress and each
        # checkpoint as it lands (mean of the Combined pass then).
        engine = vdbphoton_export.VdbphotonRenderEngine
        seen = {'progress': [], 'checkpoints': []}
        show_progress, show_checkpoint = engine.show_progress, engine.show_checkpoint

        def progress(self, fraction, text):
            seen['progress'].append([fraction, text])
            show_progress(self, fraction, text)

        def checkpoint(self, result, passes):
            px = result.layers[0].passes['Combined'].rect
            n = len(px)
            seen['checkpoints'].append([passes, sum(p[0] for p in px) / max(n, 1)])
            show_checkpoint(self, result, passes)

        engine.show_progress, engine.show_checkpoint = progress, checkpoint
        sc.vdbphoton.samples = 400
        sc.vdbphoton.checkpoint = 0.1
        bpy.ops.render.render(write_still=True)
        engine.show_progress, engine.show_checkpoint = show_progress, show_checkpoint
        sc.vdbphoton.samples = 16
        found['seen'] = seen
        # And F12 at 16 samples, compared with the command line.
        bpy.ops.render.render(write_still=True)
        found['saved'] = os.path.isfile(path)
        first = open(path, 'rb').read()
        # A folder that cannot be written: Blender's report, the earlier
        # image kept.
        sc.render.filepath = '/sys/vdbphoton-test/still.exr'
        try:
            bpy.ops.render.render(write_still=True)
            found['readonly_error'] = None
        except RuntimeError as e:
            found['readonly_error'] = str(e)
        found['earlier_kept'] = open(path, 'rb').read() == first
        # The panel: shown for this engine only, with the settings that
        # matter (drawn into a layout that records what it is given).
        panel = vdbphoton_export.RENDER_PT_vdbphoton
        drawn = []

        class Layout:
            use_property_split = False

            def column(self):
                return self

            def prop(self, data, name):
                drawn.append(name)

        panel.draw(SimpleNamespace(layout=Layout()), SimpleNamespace(scene=sc))
        found['panel'] = {'drawn': drawn,
                          'ours': panel.poll(SimpleNamespace(engine='VDBPHOTON')),
                          'cycles': panel.poll(SimpleNamespace(engine='CYCLES')),
                          'format_panel': 'VDBPHOTON' in bpy.types.RENDER_PT_format.COMPAT_ENGINES}
        # The scene as the engine exports it, and its command line.
        toml = os.path.join(out_dir, 'still.toml')
        vdbphoton_export.export_scene(toml, sc, frames=str(sc.frame_current),
                                      output=os.path.join(out_dir, 'cli.exr'), no_preview=True)
        found['command'] = vdbphoton_export.engine_command(
            os.environ['VDBPHOTON'], toml, os.path.join(out_dir, 'cli.exr'),
            sc.frame_current, sc.vdbphoton)
        # The exporter writes a still as the current frame, not 1-250.
        plain = os.path.join(out_dir, 'plain.toml')
        vdbphoton_export.export_scene(plain, sc)
        found['frames_line'] = [line for line in open(plain) if line.startswith('frames')]
    elif case == 'denoise':
        sc.vdbphoton.denoise = True
        path = os.path.join(out_dir, 'denoised.exr')
        sc.render.filepath = path
        bpy.ops.render.render(write_still=True)
        found['saved'] = os.path.isfile(path)
        toml = os.path.join(out_dir, 'denoise.toml')
        vdbphoton_export.export_scene(toml, sc, frames=str(sc.frame_current),
                                      output=os.path.join(out_dir, 'cli.exr'), no_preview=True)
        found['command'] = vdbphoton_export.engine_command(
            os.environ['VDBPHOTON'], toml, os.path.join(out_dir, 'cli.exr'),
            sc.frame_current, sc.vdbphoton)
    elif case == 'border':
        # F12 of the whole frame, then of a border (cropped): the border's
        # pixels are the whole frame's there (vdbphoton renders the region
        # with the whole frame's streams).
        whole = os.path.join(out_dir, 'whole.exr')
        sc.render.filepath = whole
        bpy.ops.render.render(write_still=True)
        r = sc.render
        r.use_border, r.use_crop_to_border = True, True
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.0, 0.5
        part = os.path.join(out_dir, 'border.exr')
        sc.render.filepath = part
        bpy.ops.render.render(write_still=True)
        found['files'] = [os.path.isfile(whole), os.path.isfile(part)]
    elif case == 'layers':
        # Two view layers: each gets its own image (Blender calls the
        # engine once a layer).
        sc.view_layers.new('Second')
        path = os.path.join(out_dir, 'layers.exr')
        sc.render.filepath = path
        bpy.ops.render.render(write_still=True)
        found['files'] = [os.path.isfile(path)]
    elif case == 'animation':
        sc.frame_start, sc.frame_end = 1, 2
        sc.render.filepath = os.path.join(out_dir, 'anim_')
        bpy.ops.render.render(animation=True)
        found['files'] = sorted(f for f in os.listdir(out_dir) if f.startswith('anim_'))
    elif case == 'catcherpass':
        # The Shadow Catcher pass is registered as Cycles registers it: when
        # the view layer asks for it, and (ours) whenever the scene has a
        # catcher; without a catcher in the render it is 1 everywhere.
        engine = vdbphoton_export.VdbphotonRenderEngine
        vl = sc.view_layers[0]

        def registered():
            names = []
            rec = SimpleNamespace(register_pass=lambda scene, layer, name, *a: names.append(name))
            engine.update_render_passes(rec, sc, vl)
            return names

        found['registered'] = {'plain': registered()}
        vl.cycles.use_pass_shadow_catcher = True
        found['registered']['view_layer_pass'] = registered()
        vl.cycles.use_pass_shadow_catcher = False
        plane = bpy.data.meshes.new('Ground')
        plane.from_pydata([(-3, -3, -1), (3, -3, -1), (3, 3, -1), (-3, 3, -1)], [], [(0, 1, 2, 3)])
        ground = bpy.data.objects.new('Ground', plane)
        ground.is_shadow_catcher = True
        holder = bpy.data.collections.new('Held')
        holder.objects.link(ground)
        inst = bpy.data.objects.new('Held instance', None)
        inst.instance_type = 'COLLECTION'
        inst.instance_collection = holder
        sc.collection.objects.link(inst)
        found['registered']['instanced_catcher'] = registered()
        bpy.data.objects.remove(inst)
        vl.cycles.use_pass_shadow_catcher = True
        path = os.path.join(out_dir, 'nocatcher.exr')
        sc.render.filepath = path
        bpy.ops.render.render(write_still=True)
        found['saved'] = os.path.isfile(path)
    elif case == 'catcher':
        # A ground plane as shadow catcher and a holdout ball in front of
        # the cloud, film transparent: F12 shows vdbphoton's shadow_catcher
        # layer as the Shadow Catcher pass.
        plane = bpy.data.meshes.new('Ground')
        plane.from_pydata([(-3, -3, -1), (3, -3, -1), (3, 3, -1), (-3, 3, -1)], [], [(0, 1, 2, 3)])
        ground = bpy.data.objects.new('Ground', plane)
        ground.is_shadow_catcher = True
        sc.collection.objects.link(ground)
        ball = bpy.data.meshes.new('Ball')
        import bmesh
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=0.3)
        bm.to_mesh(ball)
        bm.free()
        bo = bpy.data.objects.new('Ball', ball)
        bo.location = (0.3, -1.5, 0.3)
        bo.is_holdout = True
        sc.collection.objects.link(bo)
        sc.render.film_transparent = True
        path = os.path.join(out_dir, 'catcher.exr')
        sc.render.filepath = path
        try:
            bpy.ops.render.render(write_still=True)
        except RuntimeError as e:
            found['error'] = str(e)
        found['saved'] = os.path.isfile(path)
        toml = os.path.join(out_dir, 'catcher.toml')
        vdbphoton_export.export_scene(toml, sc, frames=str(sc.frame_current),
                                      output=os.path.join(out_dir, 'cli.exr'), no_preview=True)
        found['command'] = vdbphoton_export.engine_command(
            os.environ['VDBPHOTON'], toml, os.path.join(out_dir, 'cli.exr'),
            sc.frame_current, sc.vdbphoton)
    elif case in ('nocamera', 'novolume', 'missingvdb'):
        if case == 'nocamera':
            sc.camera = None
        elif case == 'novolume':
            bpy.data.objects.remove(bpy.data.objects['Cloud'])
        else:
            bpy.data.volumes['Cloud'].filepath = os.path.join(out_dir, 'gone.vdb')
        render_reporting_error(sc, os.path.join(out_dir, 'bad.exr'), found)
    elif case in ('broken', 'missing'):
        os.environ['VDBPHOTON'] = '/bin/true' if case == 'broken' else '/nonexistent/vdbphoton'
        render_reporting_error(sc, os.path.join(out_dir, 'broken.exr'), found)
    elif case == 'cancel':
        sc.vdbphoton.samples = 1 << 20
        sc.vdbphoton.checkpoint = 0.3
        t0 = time.monotonic()
        marks = {}
        engine = vdbphoton_export.VdbphotonRenderEngine

        def stop_requested(self):
            if time.monotonic() - t0 > 1.5:
                marks.setdefault('break', time.monotonic())
                return True
            return False

        engine.stop_requested = stop_requested
        sc.render.filepath = os.path.join(out_dir, 'cancel.exr')
        bpy.ops.render.render(write_still=True)
        done = time.monotonic()
        found['seconds_after_break'] = done - marks['break'] if 'break' in marks else None
        # No vdbphoton of ours left running (/proc: children of this
        # process whose command line names a render folder; other tests
        # running beside this one have renders of their own).
        alive = []
        for pid in os.listdir('/proc'):
            if pid.isdigit():
                try:
                    cmd = open(f'/proc/{pid}/cmdline', 'rb').read().decode(errors='replace')
                    stat = open(f'/proc/{pid}/stat').read()
                except OSError:
                    continue
                parent = int(stat.rsplit(')', 1)[1].split()[1])
                if parent == os.getpid() and 'vdbphoton-render-' in cmd and 'render' in cmd:
                    alive.append(pid)
        found['alive'] = alive
        found['temp_left'] = [d for d in os.listdir(os.environ.get('TMPDIR', '/tmp'))
                              if d.startswith('vdbphoton-render-')]
    print('ENGINE ' + json.dumps(found), flush=True)


try:
    main(sys.argv[1], sys.argv[2], sys.argv[3])
except Exception as e:  # noqa: BLE001
    import traceback
    traceback.print_exc()
    print(f'engine_render: {type(e).__name__}: {e}', file=sys.stderr, flush=True)
    os._exit(1)
os._exit(0)
