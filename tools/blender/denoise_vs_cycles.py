"""Denoised images at equal time: vdbphoton + Open Image Denoise against
Blender 5.0.1 Cycles + Open Image Denoise, both measured against a ground
truth.

Usage:
    nice -n 5 VENV/bin/python tools/blender/denoise_vs_cycles.py SCENE.toml TRUTH.exr [TRUTH2.exr] \
        --out DIR [--budgets 10,30] [--integrators auto,path,photon] [--threads 2] \
        [--vdbphoton target/release/vdbphoton] [--no-cycles] [--seeds 1,2,3]

VENV is the Python 3.11 venv with `pip install bpy==5.0.1`
(target/venv-bpy); it needs nothing else (numpy comes with bpy). Run it
under `nice`: the renders inherit it. One render runs at a time.

What it measures, for each budget B (seconds) in --budgets:
  1. Cycles (render_cycles.py's scene and unbiased settings, the scene's
     seed) with its denoiser as /work/shared/REFERENCE.md gives it
     (use_denoising, OPENIMAGEDENOISE, input passes RGB_ALBEDO_NORMAL,
     prefilter ACCURATE, quality HIGH, on the CPU), samples 2^24 and
     time_limit = B. Time: the wall time of bpy.ops.render.render (scene
     synchronisation - for a VDB, loading it and building Cycles' volume
     octree -, path tracing for B seconds, denoising). The view layer's
     Denoising Data is on, so the render result also holds the "Noisy
     Image" pass, the raw render the denoiser was given (same samples): the
     script writes both from one render. The samples Cycles reached are the
     last "Sample N/M" of its render status (bpy.app.handlers.render_stats;
     the EXR's cycles.*.samples metadata holds the requested 2^24, and the
     Debug Sample Count pass is normalised to 1); the status times also
     split the wall time into sync (until "Sample 0"), path tracing (until
     the last sample) and the rest (denoising, writing the result).
  2. `vdbphoton render SCENE --time Bs --denoise --threads T --integrator I`
     for each I of --integrators (auto: the scene's own choice, recorded as
     the integrator it picked), the wall time of the whole process (start,
     loading, rendering until the budget, denoising, writing). Passes and spp
     come from the EXR's header.
  3. For every image, raw and denoised: relMSE = mean((a - t)^2 / (t^2 +
     0.01)) over pixels and R, G, B, and the image-mean ratio mean(a) / mean(t)
     (means over pixels and R, G, B), t the ground truth: `vdbphoton
     compare`'s definitions.
Before each measurement the load average (/proc/loadavg, as `uptime`
prints it) is recorded.

With --seeds, every renderer renders each budget once per seed (Cycles'
`seed`, vdbphoton's `--seed`; files named ..._{B}s_seed{S}...), and a
second table gives each renderer's relMSEs averaged over the seeds and
ours over Cycles' mean: a denoised image's error varies by 10-20 % from
seed to seed (on the dense cloud at 10 s, Cycles 5.0e-4 to 6.2e-4), more
than many a change one wants to measure.

The ground truth: TRUTH.exr's RGBA; given two (independent renders of one
scene with equal samples), their mean, written to DIR/truth_mean.exr, and
the two halves' relMSE against each other is reported (the mean's own
squared error is about a quarter of it).

Output, all in DIR (created if missing):
  cycles_{B}s.exr            Cycles' multilayer EXR (one part per pass: Combined =
                             denoised, Noisy Image = raw, Denoising Albedo/Normal/Depth)
  cycles_{B}s_denoised.exr,  the same two images as plain RGBA EXRs (for
  cycles_{B}s_raw.exr        `vdbphoton compare`)
  ours_{I}_{B}s.exr          vdbphoton's EXR: RGBA = denoised, layer `noisy` = raw
  ours_{I}_{B}s_raw.exr      its raw image as plain RGBA
  ours_{I}_{B}s.log          vdbphoton's output
  truth_mean.exr             with two truths
  results.md, results.json   the table and every figure
and the table on stdout: scene, budget, renderer, integrator, wall time,
spp / passes, relMSE raw, relMSE denoised, mean ratio denoised (and raw),
and our denoised relMSE / Cycles' denoised relMSE at the same budget.

EXRs are read and written by the small scan-line reader/writer below
(single- or multi-part, HALF/FLOAT/UINT, compression NONE, ZIPS or ZIP;
written as float32 ZIP), since Blender's image loader shows only the first
pass of a multilayer file. Scenes: anything render_cycles.py renders; a
[render] `integrator` or `denoise` key is dropped for Cycles (a path tracer
here, denoised by this script) and kept for vdbphoton (--integrator
overrides the first, --denoise the second).
"""
import argparse
import copy
import hashlib
import json
import os
import re
import struct
import subprocess
import sys
import time
import zlib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)

CYCLES_MAX_SAMPLES = 1 << 24            # Cycles' hard maximum


# ------------------------------------------------------------------- EXR I/O

def _read_headers(data, multipart):
    pos, parts = 8, []
    while True:
        attrs = {}
        while data[pos] != 0:
            end = data.index(b'\0', pos)
            name = data[pos:end].decode()
            pos = end + 1
            end = data.index(b'\0', pos)
            typ = data[pos:end].decode()
            pos = end + 1
            size = struct.unpack_from('<i', data, pos)[0]
            pos += 4
            attrs[name] = (typ, data[pos:pos + size])
            pos += size
        pos += 1
        parts.append(attrs)
        if not multipart or data[pos] == 0:
            break
    if multipart:
        pos += 1                        # the empty header ending the list
    return parts, pos


def read_exr(path):
    """(channels, metadata) of a scan-line EXR: channels by full name
    ('R', 'noisy.R', 'ViewLayer.Noisy Image.R') as float64 arrays, rows top
    first; metadata = its string attributes."""
    with open(path, 'rb') as f:
        data = f.read()
    if data[:4] != b'\x76\x2f\x31\x01':
        raise ValueError(f'{path}: not an OpenEXR file')
    flags = struct.unpack_from('<I', data, 4)[0]
    if flags & 0x200:
        raise ValueError(f'{path}: tiled EXR not supported')
    multipart = bool(flags & 0x1000)
    parts, pos = _read_headers(data, multipart)
    sizes = {0: 4, 1: 2, 2: 4}                      # UINT, HALF, FLOAT
    dtypes = {0: '<u4', 1: '<f2', 2: '<f4'}
    channels, meta = {}, {}
    for attrs in parts:
        for k, (t, v) in attrs.items():
            if t == 'string':
                meta[k] = v.decode('utf-8', 'replace')
        chans, raw, p = [], attrs['channels'][1], 0
        while raw[p] != 0:
            end = raw.index(b'\0', p)
            ptype, _, xs, ys = struct.unpack_from('<iB3xii', raw, end + 1)
            if xs != 1 or ys != 1:
                raise ValueError(f'{path}: subsampled channel')
            chans.append((raw[p:end].decode(), ptype))
            p = end + 17
        x0, y0, x1, y1 = struct.unpack('<iiii', attrs['dataWindow'][1])
        w, h = x1 - x0 + 1, y1 - y0 + 1
        comp = attrs['compression'][1][0]
        lines = {0: 1, 2: 1, 3: 16}.get(comp)
        if lines is None:
            raise ValueError(f'{path}: compression {comp} not supported (NONE, ZIPS, ZIP)')
        nblocks = (h + lines - 1) // lines
        offsets = struct.unpack_from(f'<{nblocks}Q', data, pos)
        pos += 8 * nblocks
        img = {name: np.zeros((h, w)) for name, _ in chans}
        line_bytes = w * sum(sizes[t] for _, t in chans)
        for off in offsets:
            if multipart:
                off += 4                                # the part number
            y, n = struct.unpack_from('<ii', data, off)
            block = data[off + 8:off + 8 + n]
            nl = min(lines, y1 - y + 1)
            if comp != 0 and n < nl * line_bytes:
                b = np.frombuffer(zlib.decompress(block), dtype=np.uint8).astype(np.int32)
                # Undo the predictor, then the interleaving of the two halves.
                b = (np.cumsum(np.concatenate(([b[0]], b[1:] - 128))) & 0xFF).astype(np.uint8)
                half = (len(b) + 1) // 2
                t = np.empty(len(b), dtype=np.uint8)
                t[0::2] = b[:half]
                t[1::2] = b[half:]
                block = t.tobytes()
            q = 0
            for line in range(nl):
                for name, t in chans:
                    k = w * sizes[t]
                    img[name][y - y0 + line] = np.frombuffer(block[q:q + k], dtype=dtypes[t])
                    q += k
        channels.update(img)
    return channels, meta


def rgba(channels, prefix=''):
    """H x W x 4 array of the channels prefix + R, G, B, A (A = 1 if absent)."""
    rgb = [channels[prefix + c] for c in 'RGB']
    a = channels.get(prefix + 'A', np.ones_like(rgb[0]))
    return np.stack(rgb + [a], axis=-1)


def write_exr(path, img, meta=None):
    """Writes an H x W x 4 image as a float32 RGBA scan-line EXR (ZIP, 16
    lines a block), through a temporary name; meta: extra string attributes."""
    h, w, _ = img.shape

    def attr(name, typ, value):
        return name.encode() + b'\0' + typ.encode() + b'\0' + struct.pack('<i', len(value)) + value

    chlist = b''.join(c.encode() + b'\0' + struct.pack('<iB3xii', 2, 0, 1, 1) for c in 'ABGR') + b'\0'
    box = struct.pack('<iiii', 0, 0, w - 1, h - 1)
    head = b'\x76\x2f\x31\x01' + struct.pack('<I', 2)
    head += attr('channels', 'chlist', chlist)
    head += attr('compression', 'compression', b'\x03')
    head += attr('dataWindow', 'box2i', box)
    head += attr('displayWindow', 'box2i', box)
    head += attr('lineOrder', 'lineOrder', b'\x00')
    head += attr('pixelAspectRatio', 'float', struct.pack('<f', 1.0))
    head += attr('screenWindowCenter', 'v2f', struct.pack('<ff', 0.0, 0.0))
    head += attr('screenWindowWidth', 'float', struct.pack('<f', 1.0))
    for k, v in (meta or {}).items():
        head += attr(k, 'string', str(v).encode())
    head += b'\0'
    f32 = img.astype('<f4')
    blocks = []
    for y in range(0, h, 16):
        rows = f32[y:y + 16]
        raw = b''.join(rows[r, :, c].tobytes() for r in range(rows.shape[0]) for c in (3, 2, 1, 0))
        b = np.frombuffer(raw, dtype=np.uint8)
        t = np.concatenate((b[0::2], b[1::2])).astype(np.int32)
        d = t.copy()
        d[1:] = (t[1:] - t[:-1] + 128) & 0xFF
        packed = zlib.compress(d.astype(np.uint8).tobytes())
        if len(packed) >= len(raw):
            packed = raw                                # stored uncompressed
        blocks.append(struct.pack('<ii', y, len(packed)) + packed)
    table_end = len(head) + 8 * len(blocks)
    offsets, pos = [], table_end
    for blk in blocks:
        offsets.append(pos)
        pos += len(blk)
    tmp = f'{path}.{os.getpid()}.tmp'
    with open(tmp, 'wb') as f:
        f.write(head + struct.pack(f'<{len(offsets)}Q', *offsets) + b''.join(blocks))
    os.replace(tmp, path)


# ------------------------------------------------------------------- metrics

def relmse(a, ref):
    """vdbphoton compare's relative MSE over pixels and R, G, B."""
    a, ref = a[..., :3], ref[..., :3]
    return float(np.mean((a - ref) ** 2 / (ref ** 2 + 0.01)))


def mean_ratio(a, ref):
    return float(a[..., :3].mean() / ref[..., :3].mean())


def loadavg():
    with open('/proc/loadavg') as f:
        return ' '.join(f.read().split()[:3])


# -------------------------------------------------------------------- Cycles

def tag(budget, seed):
    """The part of a file name that tells a budget's (and a seed's) renders."""
    return f'{budget:g}s' + ('' if seed is None else f'_seed{seed}')


def render_cycles_denoised(scene_path, budget, out_dir, threads, seed=None):
    """One Cycles render with OIDN for `budget` seconds (with `seed`, or
    the scene's); writes the multilayer EXR and the raw and denoised images;
    returns the record."""
    import bpy
    import render_cycles

    desc = copy.deepcopy(render_cycles.load_scene(scene_path))
    r = desc.get('render', {})
    dropped = [k for k in ('integrator', 'denoise') if isinstance(r, dict) and r.pop(k, None) is not None]
    args = argparse.Namespace(width=None, height=None, spp=None, seed=seed, threads=threads,
                              half=False)
    notes = []
    scene, info, _ = render_cycles.build_scene(desc, args, os.path.dirname(scene_path), None, notes)
    cy = scene.cycles
    cy.samples = CYCLES_MAX_SAMPLES
    cy.time_limit = float(budget)
    cy.use_denoising = True
    cy.denoiser = 'OPENIMAGEDENOISE'
    cy.denoising_input_passes = 'RGB_ALBEDO_NORMAL'
    cy.denoising_prefilter = 'ACCURATE'
    cy.denoising_quality = 'HIGH'
    cy.denoising_use_gpu = False
    scene.view_layers[0].cycles.denoising_store_passes = True    # adds "Noisy Image"
    scene.render.image_settings.media_type = 'MULTI_LAYER_IMAGE'
    scene.render.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    scene.render.image_settings.color_depth = '32'
    scene.render.image_settings.exr_codec = 'ZIP'

    status = []                                   # (seconds since start, status text)
    t0 = None

    def on_stats(text, *_):
        status.append((time.time() - t0, str(text)))

    bpy.app.handlers.render_stats.append(on_stats)
    load = loadavg()
    try:
        t0 = time.time()
        bpy.ops.render.render(write_still=False)
        wall = time.time() - t0
    finally:
        bpy.app.handlers.render_stats.remove(on_stats)

    out = os.path.join(out_dir, f'cycles_{tag(budget, seed)}.exr')
    render_cycles.save_exr(scene, out)
    ch, meta = read_exr(out)
    layer = scene.view_layers[0].name
    den = rgba(ch, f'{layer}.Combined.')
    raw = rgba(ch, f'{layer}.Noisy Image.')
    write_exr(os.path.join(out_dir, f'cycles_{tag(budget, seed)}_denoised.exr'), den)
    write_exr(os.path.join(out_dir, f'cycles_{tag(budget, seed)}_raw.exr'), raw)

    samples, t_first, t_last = 0, None, None
    for t, s in status:
        m = re.search(r'Sample (\d+)/', s)
        if not m:
            continue
        n = int(m.group(1))
        if t_first is None:
            t_first = t
        if n > samples:
            samples, t_last = n, t
    return dict(renderer='cycles', integrator='path', budget=budget, load=load, wall=wall,
                spp=samples, passes=samples, seed=info['seed'], raw=raw, denoised=den,
                sync=t_first, path_trace=(t_last - t_first) if t_last is not None else None,
                after=(wall - t_last) if t_last is not None else None,
                cycles_meta={k: v for k, v in meta.items() if k.startswith('cycles.') or k == 'Software'},
                file=out, notes=notes + [f'[render] {k} dropped for Cycles' for k in dropped])


# ----------------------------------------------------------------- vdbphoton

def render_ours(binary, scene_path, budget, integrator, out_dir, threads, seed=None):
    name = f'ours_{integrator}_{tag(budget, seed)}'
    out = os.path.join(out_dir, f'{name}.exr')
    cmd = [binary, 'render', scene_path, '--time', f'{budget:g}s', '--denoise',
           '--threads', str(threads), '--integrator', integrator, '-o', out,
           '--no-preview', '--quiet'] + ([] if seed is None else ['--seed', str(seed)])
    load = loadavg()
    t0 = time.time()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.time() - t0
    with open(os.path.join(out_dir, f'{name}.log'), 'w') as f:
        f.write(' '.join(cmd) + '\n' + p.stdout)
    if p.returncode != 0:
        raise RuntimeError(f'{" ".join(cmd)} failed ({p.returncode}):\n{p.stdout}')
    ch, meta = read_exr(out)
    den = rgba(ch)
    raw = rgba(ch, 'noisy.')
    write_exr(os.path.join(out_dir, f'{name}_raw.exr'), raw)
    summary = [line for line in p.stdout.splitlines() if line.startswith('rendered ')]
    return dict(renderer='vdbphoton', integrator=integrator, budget=budget, load=load,
                wall=wall, used=meta.get('vdbphoton/integrator'),
                spp=int(meta.get('vdbphoton/spp', 0)), passes=int(meta.get('vdbphoton/passes', 0)),
                render_seconds=float(meta.get('vdbphoton/render_seconds', 'nan')),
                seed=meta.get('vdbphoton/seed'), denoise=meta.get('vdbphoton/denoise'),
                raw=raw, denoised=den, file=out, command=' '.join(cmd),
                summary=summary[-1] if summary else '')


# ---------------------------------------------------------------------- main

def fmt(x, spec):
    return '-' if x is None else format(x, spec)


def mean_table(scene_name, rows):
    """Per budget and renderer, the relMSEs' means over the seeds, and
    ours over Cycles' mean denoised relMSE."""
    head = ['scene', 'budget', 'renderer', 'integrator', 'seeds', 'mean spp', 'mean relMSE raw',
            'mean relMSE denoised', 'ours/cycles denoised (means)']
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    groups = {}
    for r in rows:
        groups.setdefault((r['budget'], r['renderer'], r['integrator']), []).append(r)
    for (b, renderer, integ), rs in groups.items():
        den = sum(r['relmse_denoised'] for r in rs) / len(rs)
        cyc = groups.get((b, 'cycles', 'path'))
        vs = None
        if cyc is not None and renderer != 'cycles':
            vs = den / (sum(r['relmse_denoised'] for r in cyc) / len(cyc))
        lines.append('| ' + ' | '.join([
            scene_name, f'{b:g} s', renderer, integ, str(len(rs)),
            f"{sum(r['spp'] for r in rs) / len(rs):.0f}",
            f"{sum(r['relmse_raw'] for r in rs) / len(rs):.4g}", f'{den:.4g}',
            fmt(vs, '.3f')]) + ' |')
    return '\n'.join(lines)


def table(scene_name, rows):
    head = ['scene', 'budget', 'seed', 'renderer', 'integrator', 'load', 'wall s', 'spp/passes',
            'relMSE raw', 'relMSE denoised', 'mean ratio denoised', 'mean ratio raw',
            'ours/cycles denoised']
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for r in rows:
        integ = r['integrator'] + (f" ({r['used']})" if r.get('used') and r['used'] != r['integrator'] else '')
        sp = f"{r['spp']}" if r['renderer'] == 'cycles' else f"{r['spp']} / {r['passes']}"
        lines.append('| ' + ' | '.join([
            scene_name, f"{r['budget']:g} s", fmt(r.get('asked_seed'), ''), r['renderer'], integ,
            r['load'], f"{r['wall']:.2f}", sp,
            f"{r['relmse_raw']:.4g}", f"{r['relmse_denoised']:.4g}",
            f"{r['ratio_denoised']:.5f}", f"{r['ratio_raw']:.5f}",
            fmt(r.get('vs_cycles'), '.3f')]) + ' |')
    return '\n'.join(lines)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('truth', nargs='+', help='the ground truth EXR, or two to average')
    ap.add_argument('--out', required=True, help='output folder (created if missing)')
    ap.add_argument('--budgets', default='10,30', help='seconds, comma-separated (default 10,30)')
    ap.add_argument('--integrators', default='auto,path,photon')
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--vdbphoton', default=os.path.join(REPO, 'target', 'release', 'vdbphoton'))
    ap.add_argument('--no-cycles', action='store_true', help='skip the Cycles renders')
    ap.add_argument('--seeds', default='',
                    help='comma-separated seeds: every renderer renders each budget once per seed '
                         '(a denoised image\'s error varies from seed to seed by 10-20 %%), and a '
                         'second table gives the means over seeds (default: each renderer\'s own seed, once)')
    a = ap.parse_args(argv)
    if len(a.truth) > 2:
        ap.error('give one ground truth EXR or two to average')
    budgets = [float(b) for b in a.budgets.split(',') if b.strip()]
    integrators = [i.strip() for i in a.integrators.split(',') if i.strip()]
    seeds = [int(s) for s in a.seeds.split(',') if s.strip()] or [None]
    scene_path = os.path.abspath(a.scene)
    out_dir = os.path.abspath(a.out)
    os.makedirs(out_dir, exist_ok=True)
    name = os.path.splitext(os.path.basename(scene_path))[0]
    t_start = time.time()

    # Ground truth.
    truths = [rgba(read_exr(p)[0]) for p in a.truth]
    with open(a.vdbphoton, 'rb') as f:
        binary_sha = hashlib.sha256(f.read()).hexdigest()[:16]
    info = dict(scene=scene_path, truth=[os.path.abspath(p) for p in a.truth],
                vdbphoton=os.path.abspath(a.vdbphoton), vdbphoton_sha256=binary_sha,
                vdbphoton_mtime=time.strftime('%Y-%m-%d %H:%M:%S',
                                              time.localtime(os.path.getmtime(a.vdbphoton))),
                threads=a.threads,
                nice=os.nice(0), start_load=loadavg(),
                start=time.strftime('%Y-%m-%d %H:%M:%S'))
    if len(truths) == 2:
        truth = (truths[0] + truths[1]) / 2
        write_exr(os.path.join(out_dir, 'truth_mean.exr'), truth,
                  {'comment': 'mean of ' + ' and '.join(info['truth'])})
        info['truth_halves_relmse'] = relmse(truths[0], truths[1])
        info['truth_halves_mean_ratio'] = mean_ratio(truths[0], truths[1])
        print(f"truth: mean of {a.truth[0]} and {a.truth[1]} -> {out_dir}/truth_mean.exr; "
              f"halves: relMSE {info['truth_halves_relmse']:.4g}, mean ratio "
              f"{info['truth_halves_mean_ratio']:.5f} (the mean's own error ~ a quarter of that relMSE)",
              flush=True)
    else:
        truth = truths[0]
    info['truth_mean'] = float(truth[..., :3].mean())
    print(f'start {info["start"]}, load {info["start_load"]}, niceness {info["nice"]}', flush=True)

    rows = []
    for b, seed in [(b, s) for b in budgets for s in seeds]:
        batch = []
        at = f'[{b:g} s' + ('' if seed is None else f', seed {seed}') + ']'
        if not a.no_cycles:
            print(f'{at} cycles + OIDN (load {loadavg()})', flush=True)
            batch.append(render_cycles_denoised(scene_path, b, out_dir, a.threads, seed))
        for integ in integrators:
            print(f'{at} vdbphoton --integrator {integ} --denoise (load {loadavg()})', flush=True)
            batch.append(render_ours(a.vdbphoton, scene_path, b, integ, out_dir, a.threads, seed))
        for r in batch:
            r['asked_seed'] = seed
        cyc = next((r for r in batch if r['renderer'] == 'cycles'), None)
        for r in batch:
            r['relmse_raw'] = relmse(r['raw'], truth)
            r['relmse_denoised'] = relmse(r['denoised'], truth)
            r['ratio_raw'] = mean_ratio(r['raw'], truth)
            r['ratio_denoised'] = mean_ratio(r['denoised'], truth)
            if cyc is not None and r is not cyc:
                r['vs_cycles'] = r['relmse_denoised'] / cyc['relmse_denoised']
            del r['raw'], r['denoised']
            extra = ''
            if r['renderer'] == 'cycles':
                extra = (f" (sync {fmt(r['sync'], '.2f')} s, path tracing {fmt(r['path_trace'], '.2f')} s, "
                         f"denoise and rest {fmt(r['after'], '.2f')} s)")
            else:
                extra = f" ({r['summary']})"
            print(f"  {r['renderer']} {r['integrator']}: wall {r['wall']:.2f} s, spp {r['spp']}, "
                  f"relMSE raw {r['relmse_raw']:.4g} denoised {r['relmse_denoised']:.4g}{extra}",
                  flush=True)
        rows.extend(batch)

    info['wall'] = time.time() - t_start
    text = table(name, rows)
    if seeds != [None]:
        text += '\n\nMeans over the seeds ' + ', '.join(map(str, seeds)) + ':\n\n' + mean_table(name, rows)
    notes = []
    if 'truth_halves_relmse' in info:
        notes.append(f"Ground truth: mean of two renders; their relMSE against each other "
                     f"{info['truth_halves_relmse']:.4g} (mean ratio {info['truth_halves_mean_ratio']:.5f}).")
    for r in rows:
        if r['renderer'] == 'cycles':
            notes.append(f"Cycles {r['budget']:g} s: sync {fmt(r['sync'], '.2f')} s, path tracing "
                         f"{fmt(r['path_trace'], '.2f')} s, denoising and the rest "
                         f"{fmt(r['after'], '.2f')} s; {r['spp']} samples; metadata {r['cycles_meta']}"
                         + ''.join(f'; {n}' for n in r['notes']))
    md = (f"# {name}: denoised, equal time\n\n"
          f"- scene {scene_path}\n- truth {', '.join(info['truth'])}\n"
          f"- vdbphoton {info['vdbphoton']} (sha256 {binary_sha}..., built {info['vdbphoton_mtime']}), "
          f"{a.threads} threads; niceness {info['nice']}\n"
          f"- started {info['start']}, load {info['start_load']}; took {info['wall']:.0f} s\n\n"
          + text + '\n\n' + '\n'.join(f'- {n}' for n in notes) + '\n')
    with open(os.path.join(out_dir, 'results.md'), 'w') as f:
        f.write(md)
    with open(os.path.join(out_dir, 'results.json'), 'w') as f:
        json.dump(dict(info=info, rows=rows), f, indent=1)
    print()
    print(md)
    return 0


if __name__ == '__main__':
    code = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
