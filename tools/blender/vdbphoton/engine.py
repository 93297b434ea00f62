"""vdbphoton as a render engine of Blender: F12 exports the current frame
with the exporter (export.py) into a temporary folder, runs the `vdbphoton`
binary (binary.py) on it with `--progress json`, follows its progress,
draws each checkpoint into the render result, stops it on Esc, and loads
the finished EXR (beauty as Combined, the AOVs as render passes)."""

import os
import struct

import bpy

from .binary import addon_version_text, check_binary, find_binary
from .export import export_scene
from .meshes import SURFACE_TYPES
from .util import ExportError, internal_error

# Render passes from the EXR's layers: (pass name, channels, Blender's
# channel ids, EXR layer).
AOV_PASSES = [('Direct', 3, 'RGB', 'direct'), ('Indirect', 3, 'RGB', 'indirect'),
              ('Emission', 3, 'RGB', 'emission'), ('Transmittance', 1, 'X', 'transmittance')]
DENOISE_PASSES = [('Noisy Image', 4, 'RGBA', 'noisy'), ('Denoising Albedo', 3, 'RGB', 'albedo')]
# Cycles' Shadow Catcher pass (its add-on's engine.py names it so): the EXR's
# layer `shadow_catcher`, 1 where no catcher is seen; composite = Combined
# over (background x Shadow Catcher).
CATCHER_PASS = ('Shadow Catcher', 3, 'RGB', 'shadow_catcher')


def scene_has_shadow_catcher(scene):
    """Whether an object of `scene`, or of a collection its objects
    instance, is a shadow catcher (Object > Visibility > Mask)."""
    seen = set()

    def walk(objects):
        for o in objects:
            # (A light's flag reads True in Blender 5.0.1; only geometry and
            # instancers count.)
            if o.type in SURFACE_TYPES + ('EMPTY',) and getattr(o, 'is_shadow_catcher', False):
                return True
            c = o.instance_collection if o.instance_type == 'COLLECTION' else None
            if c is not None and c.name_full not in seen:
                seen.add(c.name_full)
                if walk(c.all_objects):
                    return True
        return False

    return walk(scene.objects)


def wants_shadow_catcher(scene, view_layer):
    """The Shadow Catcher pass is registered as Cycles registers it, when
    the view layer asks for it (View Layer Properties > Passes > Shadow
    Catcher), and whenever the scene has a shadow catcher."""
    cy = getattr(view_layer, 'cycles', None) if view_layer is not None else None
    if cy is not None and getattr(cy, 'use_pass_shadow_catcher', False):
        return True
    return scene is not None and scene_has_shadow_catcher(scene)


def engine_passes(scene, view_layer, denoise):
    """The passes beside Combined, as update_render_passes registers them."""
    return AOV_PASSES + (DENOISE_PASSES if denoise else []) + \
        ([CATCHER_PASS] if wants_shadow_catcher(scene, view_layer) else [])


def read_exr_channels(path):
    """The channels of a scan-line EXR as vdbphoton writes it (single part,
    ZIP, ZIPS or no compression), float32 arrays of shape (height, width),
    top row first, and the display size."""
    import numpy as np
    import zlib
    with open(path, 'rb') as f:
        data = f.read()
    if data[:4] != b'\x76\x2f\x31\x01':
        raise ExportError(f'{path}: not an OpenEXR file')
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b'\0', pos)
        name = data[pos:end].decode()
        end2 = data.index(b'\0', end + 1)
        size = struct.unpack_from('<i', data, end2 + 1)[0]
        attrs[name] = data[end2 + 5:end2 + 5 + size]
        pos = end2 + 5 + size
    pos += 1
    chans, raw, p = [], attrs['channels'], 0
    while raw[p] != 0:
        end = raw.index(b'\0', p)
        chans.append((raw[p:end].decode(), struct.unpack_from('<i', raw, end + 1)[0]))
        p = end + 17
    x0, y0, x1, y1 = struct.unpack('<iiii', attrs['dataWindow'])
    dx0, dy0, dx1, dy1 = struct.unpack('<iiii', attrs['displayWindow'])
    comp = attrs['compression'][0]
    lines = {0: 1, 2: 1, 3: 16}.get(comp)
    if lines is None:
        raise ExportError(f'{path}: EXR compression {comp} is not one vdbphoton writes')
    w, h = x1 - x0 + 1, y1 - y0 + 1
    size = {0: 4, 1: 2, 2: 4}
    dtype = {0: '<u4', 1: '<f2', 2: '<f4'}
    out = {n: np.zeros((h, w), dtype=np.float32) for n, _ in chans}
    nblocks = (h + lines - 1) // lines
    for off in struct.unpack_from(f'<{nblocks}Q', data, pos):
        y, n = struct.unpack_from('<ii', data, off)
        block = data[off + 8:off + 8 + n]
        nl = min(lines, y1 - y + 1)
        if comp != 0 and n < nl * w * sum(size[t] for _, t in chans):
            b = np.frombuffer(zlib.decompress(block), dtype=np.uint8).astype(np.int32)
            b = (np.cumsum(np.concatenate(([b[0]], b[1:] - 128))) & 0xFF).astype(np.uint8)
            half = (len(b) + 1) // 2
            t = np.empty(len(b), dtype=np.uint8)
            t[0::2] = b[:half]
            t[1::2] = b[half:]
            block = t.tobytes()
        q = 0
        for line in range(nl):
            for name, t in chans:
                nb = w * size[t]
                out[name][y - y0 + line] = np.frombuffer(block[q:q + nb], dtype=dtype[t])
                q += nb
    return out, (x0 - dx0, y0 - dy0), (dx1 - dx0 + 1, dy1 - dy0 + 1)


def engine_command(exe, scene_file, exr, frame, s):
    """The command line the engine runs for settings `s` (the scene's
    VdbphotonSettings)."""
    args = [exe, 'render', scene_file, '--frame', str(frame), '-o', exr, '--no-preview',
            '--progress', 'json', '--addon-version', addon_version_text(),
            '--aovs', '--integrator', s.integrator,
            '--seed', str(s.seed), '--checkpoint', f'{s.checkpoint:g}s', '--no-resume-state']
    if s.budget == 'TIME':
        args += ['--time', f'{s.time_limit:g}s']
    else:
        args += ['--spp', str(s.samples)]
    if s.max_bounces > 0:
        args += ['--max-bounces', str(s.max_bounces)]
    if s.threads > 0:
        args += ['--threads', str(s.threads)]
    if s.denoise:
        args.append('--denoise')
    return args


class VdbphotonRenderEngine(bpy.types.RenderEngine):
    bl_idname = 'VDBPHOTON'
    bl_label = 'vdbphoton'
    bl_use_preview = False
    bl_use_postprocess = True

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, 'Combined', 4, 'RGBA', 'COLOR')
        denoise = scene is not None and scene.vdbphoton.denoise
        for name, n, chan, _ in engine_passes(scene, renderlayer, denoise):
            self.register_pass(scene, renderlayer, name, n, chan,
                               'VALUE' if n == 1 else 'COLOR')

    def render(self, depsgraph):
        import tempfile
        import shutil
        scene = depsgraph.scene
        try:
            exe = find_binary()
            check_binary(exe)
        except ExportError as e:
            self.report({'ERROR'}, f'vdbphoton: {e}')
            return
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, f'vdbphoton: {internal_error(e)}')
            return
        try:
            tmp = tempfile.mkdtemp(prefix='vdbphoton-render-')
        except OSError as e:
            self.report({'ERROR'}, f'vdbphoton: cannot make a temporary folder: {e}')
            return
        try:
            self._render(depsgraph, scene, exe, tmp)
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, f'vdbphoton: {internal_error(e)}')
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def _render(self, depsgraph, scene, exe, tmp):
        import queue
        import subprocess
        import threading
        s = scene.vdbphoton
        r = scene.render
        w = r.resolution_x * r.resolution_percentage // 100
        h = r.resolution_y * r.resolution_percentage // 100
        frame = scene.frame_current
        layer = depsgraph.view_layer.name
        scene_file = os.path.join(tmp, 'scene.toml')
        exr = os.path.join(tmp, 'frame.exr')
        msgs = []
        try:
            export_scene(scene_file, scene, depsgraph.view_layer,
                         warn=lambda kind, m: msgs.append((kind, m)),
                         frames=str(frame), output=exr, no_preview=True, depsgraph=depsgraph)
        except ExportError as e:
            self.report({'ERROR'}, f'vdbphoton: {e}')
            return
        except Exception as e:  # noqa: BLE001 (one report, never a traceback)
            self.report({'ERROR'}, f'vdbphoton: {internal_error(e)}')
            return
        for kind, m in msgs:
            # The engine renders a border itself (--region).
            if kind == 'warning' and 'render region (border)' not in m:
                self.report({'WARNING'}, f'vdbphoton: {m}')
        # The passes update_render_passes registered, in this view layer's
        # result (Blender calls render() once per view layer).
        passes = engine_passes(scene, depsgraph.view_layer, s.denoise)
        result = self.begin_result(0, 0, w, h, layer=layer)
        args = engine_command(exe, scene_file, exr, frame, s)
        if r.use_border:
            # Blender's result is the border (as its pipeline cuts it:
            # truncated fractions of the image, y from the bottom); render
            # just those pixels (--region, y from the top).
            x0, x1 = int(r.border_min_x * w), int(r.border_max_x * w)
            y0, y1 = int(r.border_min_y * h), int(r.border_max_y * h)
            args += ['--region', f'{x0},{h - y1},{x1},{h - y0}']
        self.update_stats('', f'vdbphoton: frame {frame}, starting')
        proc = None
        try:
            try:
                proc = subprocess.Popen(args, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.PIPE, text=True,
                                        encoding='utf-8', errors='replace', bufsize=1)
            except OSError as e:
                self.report({'ERROR'}, f"vdbphoton: cannot run '{exe}': {e}")
                return
            lines = queue.Queue()

            def pump():
                try:
                    for line in proc.stderr:
                        lines.put(line)
                finally:
                    lines.put(None)

            threading.Thread(target=pump, daemon=True).start()
            errors = []
            while True:
                try:
                    line = lines.get(timeout=0.05)
                except queue.Empty:
                    line = ''
                if line is None:
                    break
                if line:
                    self._event(line, result, passes, errors)
                if self.stop_requested():
                    # Esc: stop the render (the `finally` below). The last
                    # checkpoint drawn stays in the image.
                    self.update_stats('', 'vdbphoton: cancelled')
                    return
            rc = proc.wait()
            if rc != 0:
                # The first error names the file or setting; later ones
                # sum up.
                self.report({'ERROR'}, errors[0] if errors else
                            f'vdbphoton: the render failed (exit code {rc})')
                return
            try:
                self._load(exr, result, passes)
            except Exception as e:  # noqa: BLE001 (any unreadable image is one report)
                self.report({'ERROR'}, f'vdbphoton: cannot read the rendered image: {e}')
                return
            self.update_progress(1.0)
        finally:
            # Whatever happened: the process ends (SIGTERM, killed after a
            # second) and the result is handed back once.
            if proc is not None and proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=1.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
            self.end_result(result)

    # Blender's side of the render, as methods of ours so that a test can
    # watch them (Blender's own, `test_break`, `update_progress`, ..., are
    # RNA functions that Python cannot replace).

    def stop_requested(self):
        """Whether Blender asked to stop (Esc): `test_break`."""
        return self.test_break()

    def show_progress(self, fraction, text):
        """The progress bar and the status line."""
        self.update_progress(fraction)
        self.update_stats('', text)

    def show_checkpoint(self, result, passes):
        """A checkpoint of `passes` passes, loaded into `result`, drawn."""
        self.update_result(result)

    def _event(self, line, result, passes, errors):
        import json
        line = line.strip()
        if not line.startswith('{'):
            # Errors, and the command line's own complaints (an option this
            # binary does not know), are `vdbphoton: ...` lines.
            if line.startswith('vdbphoton: ') and not line.startswith('vdbphoton: warning:'):
                errors.append(line)
            return
        try:
            e = json.loads(line)
        except ValueError:
            return
        kind = e.get('event')
        if kind == 'progress':
            eta = e.get('eta')
            self.show_progress(min(1.0, max(0.0, float(e.get('fraction', 0.0)))),
                               f"vdbphoton: pass {e.get('passes', 0) + 1}, "
                               f"{e.get('elapsed', 0.0):.0f} s"
                               + (f', ETA {eta:.0f} s' if eta is not None else ''))
        elif kind == 'checkpoint':
            try:
                self._load(e['path'], result, passes)
            except Exception:  # noqa: BLE001 (a checkpoint not drawn is no error)
                return
            self.show_checkpoint(result, int(e.get('passes', 0)))
        elif kind == 'warning':
            self.report({'WARNING'}, f"vdbphoton: {e.get('message', '')}")

    def _load(self, path, result, passes):
        """The EXR at `path` into the render result's passes."""
        import numpy as np
        ch, _, _ = read_exr_channels(path)
        layer = result.layers[0]
        rw, rh = result.resolution_x, result.resolution_y
        dh, dw = ch['R'].shape
        if (dw, dh) != (rw, rh):
            raise ExportError(f'{path}: {dw} x {dh} pixels, the render is {rw} x {rh}')

        def put(pass_name, names):
            px = np.stack([ch[n] for n in names], axis=-1)[::-1]
            layer.passes[pass_name].rect.foreach_set(np.ascontiguousarray(px, np.float32).ravel())

        put('Combined', ['R', 'G', 'B', 'A'])
        for name, n, chan, exr_layer in passes:
            names = [f'{exr_layer}.{c}' for c in ('RGBA'[:n] if n > 1 else 'Y')]
            if all(x in ch for x in names):
                put(name, names)
            elif exr_layer == 'shadow_catcher':
                # No catcher in the render: 1 everywhere, Cycles' value
                # where no catcher is seen.
                layer.passes[name].rect.foreach_set(np.ones(rw * rh * n, dtype=np.float32))
