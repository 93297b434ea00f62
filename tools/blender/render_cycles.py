"""Render a vdbphoton scene file with Blender 5.0.1 Cycles (the `bpy` module).

Usage:
    VENV/bin/python tools/blender/render_cycles.py SCENE.toml [OUT.exr] \
        [--spp N] [--seed S] [--width W --height H] [--threads 2] \
        [--frames LIST | --frame N] [--skip-existing] [--half]

VENV is a Python 3.11 venv with `pip install bpy==5.0.1`. SCENE is a scene in
vdbphoton's format (docs/scene.md, plus the keys of the pipeline CLI: Blender
camera keys, frame patterns, [render] frames, [[volume]] bounds): TOML, or
JSON when the name ends in `.json`. Paths in it are relative to the scene
file. OUT (default: the scene's [render] output, relative to the scene) is a
float32 RGBA EXR (ZIP; half float with --half), linear, no view transform
(alpha is 1: the film is not transparent), written to a temporary name in
its folder (created if missing) and renamed when complete; it must end in
`.exr`. Command-line values override [render] spp/seed/width/height.

Frame sequences: `[[volume]] file` and OUT may hold a frame pattern,
`{frame}` (no padding), `{frame:04}` (zero-padded to 4 digits; any
`{frame:0N}` or `{frame:N}`, N <= 10) or a run of N `#` (zero-padded to N).
`--frames LIST` renders every frame of LIST (`1-40`, `1-3,5,7-20:2`: A-B
inclusive, :STEP on a range, ascending, repeats dropped; frames up to
9999999), `--frame N` one frame; without either,
[render] frames (same syntax) if the scene has it. A pattern with no frames
given is an error, and so are several frames written to an OUT without a
pattern. Each frame is a fresh Blender scene built from the scene file with
the frame substituted, rendered with the same seed (Cycles' animated seed
off), so a frame rendered alone equals the same frame of a sequence. A frame
whose volume file is missing or unreadable, or lacks a named grid, fails
with one line naming the frame and the file; the other frames still render,
and the exit code is then 1. --skip-existing skips a frame whose OUT exists
(outputs are renamed into place only when complete).

Everything that would bias a reference is off, as /work/shared/REFERENCE.md
lists and scripts/README.md checked: no clamping (direct and indirect 0), no
adaptive sampling, no light tree, light sampling threshold 0, no path
guiding, no denoising, box pixel filter of 1 px, volume precision FULL,
volume clipping 0, volume interpolation Linear, unbiased (null scattering)
volume integrator (the ray-marching one at a quarter of Cycles' default
step with motion blur: see setup_motion_blur), Standard view transform with no look/exposure/gamma, all
bounce limits (total, volume, diffuse, glossy, transmission) = B =
max_bounces - 1 (transparent 1024): vdbphoton's max_bounces counts
scattering events, Cycles counts bounces after the first one (Volume
Bounces 0 still lights the first scattering event directly). max_bounces 0
(no scattered light at all in vdbphoton) is refused for a scene whose
volumes scatter, and is B = 0 otherwise.

Mapping of the format onto Blender (conventions of docs/scene.md):
  [camera]      a perspective camera (Blender's: looks down its local -Z,
                local +Y up, clip start 1e-4, clip end 1e6).
                Lens: vfov -> sensor fit VERTICAL, angle_y = vfov (Blender
                keeps sensor_height 24 and sets lens = 12 / tan(vfov/2)).
                Or Blender's keys, copied as they are: focal_length -> Focal
                Length (lens, mm, default 50), sensor_width / sensor_height
                (mm, default 36 / 24), sensor_fit auto|horizontal|vertical
                (default auto) -> Sensor Fit; vfov may not be given with
                them, and values below Blender's 1 mm minimum are errors
                (Blender would clamp them). shift_x,
                shift_y -> Shift X / Y, with either lens (default 0).
                Orientation, one of: position/look_at/up (defaults as in
                docs/scene.md): right = normalize(forward x up), camera +Y =
                right x forward; matrix (4 rows of 4, row-major, Blender's
                matrix_world of the camera, last row 0 0 0 1) -> the
                object's world matrix, columns normalised (scale ignored, as
                Blender's view and Cycles ignore it; columns not orthogonal
                within 1e-4 or a reflection are errors); location +
                rotation (XYZ Euler, degrees, default 0 0 0; rotation needs
                location) -> the object's location and rotation_euler
                (matrix T Rz Ry Rx). framing = "auto" (with `direction`) is
                refused: it is vdbphoton's own choice of camera from the
                volumes' boxes, which a reference must be given explicitly.
                Pixel placement (checked against Blender's projection and
                Cycles renders in tests/data/camera/README.md): fit =
                horizontal if (auto and W >= H) or horizontal, else
                vertical; S = sensor_width for auto and horizontal,
                sensor_height for vertical; D = W for a horizontal fit, H for
                a vertical one; f_px = focal_length / S * D; a point at
                camera coordinates (x, y, z), z < 0 in front, lands at pixel
                (W/2 + f_px x/(-z) - shift_x D, H/2 - f_px y/(-z) + shift_y D)
                (x right, y down from the top-left corner).
  sun           Sun light, Strength = irradiance (W/m^2), Angle = angle;
                shines along -direction. Not visible to camera rays (neither
                is vdbphoton's).
  point, spot   Point/Spot light of radius 0, no soft falloff, Power =
                4*pi*intensity (W/sr); spot Size = cone_angle, Blend = blend.
  RGB values    a light's colour = value / max(value), its power/strength the
                max component.
  [environment] radiance: World Background colour, strength 1. map: an
                Environment Texture (Blender's own equirectangular mapping,
                Closest interpolation, like vdbphoton's lookup) x strength;
                rotate_z turns the map about +Z (Mapping node, Rotation Z =
                -rotate_z, so that a direction w sees the texel at
                R(-rotate_z) w, as vdbphoton's light.rs defines it).
                Measured (64 x 32 map of texel coordinates, cameras along
                +X, +Y and up, rotate_z 0 and 90): both pick the same texel
                row and the same rotation sense, but vdbphoton's map is
                turned 180 degrees about Z against Blender's (towards +X
                Cycles shows u = 0.5, the map's centre; vdbphoton u = 0,
                its edge; towards +Y Cycles u = 0.25, vdbphoton 0.75).
                This script keeps Blender's mapping, so a scene with a map
                shows that difference.
  [[volume]]    a Volume object reading `file` (with the frame + frame_offset
                substituted, as vdbphoton reads it), render Space = World
                (densities per world length, as vdbphoton's; Blender's default
                Space = Object would divide them by the object's scale,
                |M (1,1,1)/sqrt 3|);
                `bounds` ("active", "sequence", "domain" or a box) is
                checked and otherwise unused (it only steers vdbphoton's
                automatic framing); transform translate/rotate
                (XYZ Euler)/scale as the object's location/rotation/scale, or
                matrix as its world matrix (Blender applies it after the
                file's own transform, as vdbphoton does).
  Principled    a Principled Volume with the same inputs; Density Attribute =
                density_grid, Temperature Attribute = temperature_grid (empty
                without one: Cycles then uses Temperature itself, as
                vdbphoton does), Color Attribute = color_grid; a flame_grid
                multiplies Emission Strength (Attribute x Math node). A
                volume naming temperature_grid or flame_grid gets Blender's
                Quick Smoke values for what its material leaves out:
                Density 5, Blackbody Intensity 1 (as vdbphoton).
                blackbody_interpolation = "temperature" is noted: the
                Principled Volume's Temperature Attribute lookup takes one
                voxel at a time (stochastic), which is vdbphoton's
                "emission". temperature_from_flame is refused: Cycles can
                only build that temperature with shader nodes on an
                Attribute node, whose lookup interpolates the flame
                trilinearly before the mapping (Blender maps each voxel);
                measured on the Blender smoke frame 25, emission only: R +6 %,
                G -6 %, B -24 %. Render the .blend with
                test_export/render_blend.py instead, or export with
                --cache-temperature.
  raw keys      Attribute(density_grid) drives Volume Scatter (Density =
                max(sigma_s)*d, Color = sigma_s/max; HG Anisotropy g, one
                node per lobe of an hg_mix with its weight share), Volume
                Absorption (Density = max(sigma_a)*d, Color = 1 - sigma_a/max,
                since Cycles' sigma_a = Density*(1 - Color)) and Emission
                (Strength = max(emission)*d, Color = emission/max), added.

Keys it cannot reproduce stop the script with a message naming the key
(phase "schlick", render.integrator other than "path", render.aovs = true, a
seed beyond Cycles' 2^31 - 1, camera framing = "auto", max_bounces = 0 with a
scattering volume, temperature_from_flame, a per-axis velocity_scale).
Unknown keys are errors, as in vdbphoton; scene errors exit with code 2.

Motion blur ([render] motion_blur, shutter, shutter_position, fps;
[[volume]] velocity_grid, velocity_scale, velocity_unit): Blender's
Motion Blur (Shutter, Position, the scene's fps / fps_base) and each
Volume's Velocity Grid, Scale and Unit, as docs/scene.md ("Motion blur")
defines them; velocities per frame, which Cycles 5.0.1 reads without the
shutter, are scaled so that Cycles renders what they mean, and
shutter_position = "end", which Cycles misplaces, is refused
(setup_motion_blur).

Known differences that are not errors (printed as notes): vdbphoton applies
Emission Strength only where the density is > 0, and blackbody emission
without a temperature grid too; Cycles' shader runs wherever its volume mesh
(built around the active voxels of the grids) is. vdbphoton's raw keys
ignore color_grid and flame_grid; so does this script.

Printed per image: RENDER_TIME, the wall time of bpy.ops.render.render
(Cycles' scene synchronisation, i.e. VDB loading and NanoVDB / volume mesh
build, plus path tracing; the bpy module prints no per-phase times), then
`Saved: 'PATH'` once the EXR is in place (lines prefixed `frame N: ` in a
sequence, and a `frame N: T s` line on stderr); at the end TOTAL_WALL, the
whole script (Python start, bpy import, scene builds, renders, EXR writes).
"""
import argparse
import json
import math
import os
import re
import sys
import time

T_START = time.time()

try:
    import tomllib
except ImportError:  # Python < 3.11
    tomllib = None

import bpy
from mathutils import Euler, Matrix, Vector


class SceneError(Exception):
    pass


class FrameError(SceneError):
    """An input of one frame is missing or unreadable: that frame fails, the
    others still render."""


def fail(msg):
    raise SceneError(msg)


# ---------------------------------------------------------------- scene file

def load_scene(path):
    with open(path, 'rb') as f:
        data = f.read()
    if path.endswith('.json'):
        return json.loads(data.decode('utf-8'))
    if tomllib is None:
        fail('reading TOML needs Python >= 3.11 (tomllib)')
    return tomllib.loads(data.decode('utf-8'))


def check_keys(table, allowed, where):
    if not isinstance(table, dict):
        fail(f'{where} must be a table')
    for k in table:
        if k not in allowed:
            fail(f"unknown key '{k}' in {where} (expected one of: {', '.join(allowed)})")


def num(v, key):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        fail(f"key '{key}': expected a finite number, got {v!r}")
    return float(v)


def integer(v, key):
    if isinstance(v, bool) or not isinstance(v, int):
        fail(f"key '{key}': expected an integer, got {v!r}")
    return v


def vec3(v, key):
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        fail(f"key '{key}': expected [x, y, z], got {v!r}")
    return [num(x, key) for x in v]


def rgb(v, key):
    """[r, g, b] or one number meaning grey."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        x = num(v, key)
        return [x, x, x]
    return vec3(v, key)


def nonneg_rgb(v, key):
    c = rgb(v, key)
    if min(c) < 0:
        fail(f"key '{key}': must be >= 0, got {v!r}")
    return c


def split_rgb(c):
    """(colour with max component 1, that max); black gives (white, 0)."""
    m = max(c)
    if m <= 0:
        return (1.0, 1.0, 1.0), 0.0
    return tuple(x / m for x in c), m


def resolve(base, p):
    return p if os.path.isabs(p) else os.path.normpath(os.path.join(base, p))


# ------------------------------------------------------------------- frames

# {frame} (no padding), {frame:0N} or {frame:N} (zero-padded to N digits,
# N = 1..10), a run of N '#' (zero-padded to N), as vdbphoton reads them.
FRAME_PATTERN = re.compile(r'\{frame(?::0?([1-9]|10))?\}|#+')
MAX_FRAME = 9999999


def has_frame_pattern(path):
    return bool(FRAME_PATTERN.search(path))


def check_frame_pattern(path, key):
    rest = FRAME_PATTERN.sub('', path)
    if '{frame' in rest:
        fail(f"key '{key}': unknown frame pattern in {path!r} (use {{frame}}, {{frame:04}} or ####)")
    if '{tile}' in rest:
        fail(f"key '{key}': {{tile}} in {path!r}: this script renders whole frames, not tiles")


def with_frame(path, frame):
    """`path` with its frame patterns replaced by `frame` (None: unchanged)."""
    if frame is None:
        return path

    def sub(m):
        if m.group(0).startswith('#'):
            width = len(m.group(0))
        else:
            width = int(m.group(1)) if m.group(1) else 0
        return f'{frame:0{width}d}' if width else str(frame)
    return FRAME_PATTERN.sub(sub, path)


def parse_frames(text, where):
    """'1-40', '1-3,5,7-20:2' -> [1, 2, 3, 5, 7, 9, ...] (A-B inclusive,
    :STEP on a range; ascending, repeats dropped, as vdbphoton)."""
    if not isinstance(text, str):
        fail(f"{where}: expected a frame list string such as \"1-40\" or \"1-3,5,7-20:2\", "
             f"got {text!r}")
    frames = []
    for part in text.split(','):
        part = part.strip()
        m = re.fullmatch(r'(\d+)(?:\s*-\s*(\d+)(?:\s*:\s*(\d+))?)?', part)
        if not m:
            fail(f"{where}: bad frame list {text!r} at {part!r} (expected N, A-B or A-B:STEP)")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        step = int(m.group(3)) if m.group(3) is not None else 1
        if b < a:
            fail(f"{where}: bad frame list {text!r}: range {part!r} ends before it starts")
        if step < 1:
            fail(f"{where}: bad frame list {text!r}: step must be >= 1 in {part!r}")
        if b > MAX_FRAME:
            fail(f"{where}: bad frame list {text!r}: frame numbers go up to {MAX_FRAME}")
        frames.extend(range(a, b + 1, step))
    return sorted(set(frames))


# ------------------------------------------------------------------- set-up

RENDER_KEYS = ['width', 'height', 'spp', 'seed', 'max_bounces', 'integrator', 'output',
               'preview', 'exposure', 'aovs', 'frames', 'motion_blur', 'shutter',
               'shutter_position', 'fps']


def motion_blur(r):
    """[render] motion_blur, shutter (frames), shutter_position, fps, with
    vdbphoton's defaults; None when motion blur is off."""
    on = r.get('motion_blur', False)
    if not isinstance(on, bool):
        fail(f"key 'motion_blur' in [render]: expected true or false, got {on!r}")
    shutter = num(r.get('shutter', 0.5), 'render.shutter')
    position = r.get('shutter_position', 'center')
    fps = num(r.get('fps', 24.0), 'render.fps')
    if position not in ('start', 'center', 'end'):
        fail(f"key 'shutter_position' in [render]: expected \"start\", \"center\" or \"end\", "
             f"got {position!r}")
    if not (0.0 <= shutter <= 1000.0):
        fail(f"key 'shutter' in [render]: must be in [0, 1000] frames, got {shutter}")
    if not fps > 0.0:
        fail(f"key 'fps' in [render]: must be more than 0, got {fps}")
    return dict(shutter=shutter, position=position, fps=fps) if on else None


def setup_motion_blur(scene, mb):
    """Cycles' motion blur as vdbphoton's (docs/scene.md, Motion blur).
    Cycles 5.0.1 differs in two ways, measured (a box moving at a known
    speed, its smear's ends located in the image): its Position End puts
    the shutter at [(1 - s), (2 - s)] frames after the frame instead of
    [-s, 0], which no setting makes up for (a negative Velocity Scale
    would, but Blender clamps it at 0), so shutter_position = "end" is
    refused; and with velocity_unit Frame it ignores the shutter (the smear
    is always one frame's motion), so the Volume's velocity_scale is
    multiplied by the shutter there (setup_velocity). Cycles' default (null-scattering) volume
    integrator skips space where the volume is empty at the middle of the
    shutter (its density octree is built at ray time 0.5) and cuts a
    smear off there, so motion blur renders with its ray-marching
    integrator (volume_biased), at a quarter of the default step."""
    r = scene.render
    r.use_motion_blur = True
    r.motion_blur_shutter = mb['shutter']
    if mb['position'] == 'end':
        fail("key 'shutter_position' in [render]: \"end\" cannot be reproduced: Cycles 5.0.1 "
             "blurs its End over [1 - shutter, 2 - shutter] frames after the frame, not over "
             "the shutter before it (use \"start\" or \"center\")")
    r.motion_blur_position = {'start': 'START', 'center': 'CENTER'}[mb['position']]
    fps = mb['fps']
    base = max(1, min(120, round(fps)))
    r.fps = base
    r.fps_base = base / fps
    scene.cycles.volume_biased = True
    scene.cycles.volume_step_rate = 0.25
    scene.cycles.volume_max_steps = 4096


def scatters(v):
    """Whether [[volume]] `v` scatters light (sigma_s > 0)."""
    mat = v.get('material', {}) if isinstance(v, dict) else {}
    if not isinstance(mat, dict):
        return False
    if any(k in mat for k in RAW_KEYS):
        try:
            return max(rgb(mat.get('sigma_s', 0.0), 'material.sigma_s')) > 0
        except SceneError:
            return False
    smoke = 'temperature_grid' in v or 'flame_grid' in v
    try:
        d = num(mat.get('density', 5.0 if smoke else 1.0), 'material.density')
        c = rgb(mat.get('color', 0.5), 'material.color')
    except SceneError:
        return False
    return d > 0 and max(c) > 0


def cycles_bounces(mb, vols):
    """Cycles' bounce limit for vdbphoton's max_bounces. vdbphoton counts
    scattering events (a path ends at event max_bounces + 1, before its
    direct light); Cycles counts bounces after the first scattering event
    (Volume Bounces 0 still lights the first event). So B = max_bounces - 1
    (measured with the exporter: Cycles Volume 0 matches max_bounces 1
    within 0.1 %, Volume 3 matches 4). max_bounces 0 (emission and
    attenuation only) has no Cycles equivalent when a volume scatters."""
    if mb == 0:
        if any(scatters(v) for v in vols if isinstance(v, dict)):
            fail("key 'max_bounces' in [render]: 0 means no scattered light at all in "
                 "vdbphoton (a path ends at its first scattering event), which Cycles cannot "
                 "do for a scattering volume (Volume Bounces 0 still lights the first "
                 "scattering event); use max_bounces >= 1 (Cycles gets max_bounces - 1)")
        return 0
    return mb - 1


def unbiased_cycles(scene, spp, seed, threads):
    """Cycles on the CPU with every setting that would bias a reference off
    (/work/shared/REFERENCE.md): no clamping, adaptive sampling, light tree,
    path guiding or denoising; light threshold 0; a 1-pixel box filter; the
    unbiased (null-scattering) volume integrator; no motion blur (the
    caller turns it on: setup_motion_blur); no film transparency or dither; the Standard view; float32 RGBA EXR (ZIP).
    Bounce limits and the image size are the caller's. Shared with
    test_export/render_blend.py, which renders a .blend as it is."""
    scene.render.engine = 'CYCLES'
    cy = scene.cycles
    cy.device = 'CPU'
    cy.samples = spp
    cy.seed = seed
    cy.use_animated_seed = False
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.use_light_tree = False
    cy.light_sampling_threshold = 0.0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.use_guiding = False
    cy.volume_biased = False
    cy.pixel_filter_type = 'BOX'
    cy.filter_width = 1.0
    cy.transparent_max_bounces = 1024
    cy.min_light_bounces = 0
    cy.min_transparent_bounces = 0
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.blur_glossy = 0.0
    cy.time_limit = 0.0
    r = scene.render
    r.use_motion_blur = False
    r.threads_mode = 'FIXED'
    r.threads = threads
    r.film_transparent = False
    r.dither_intensity = 0.0
    vs = scene.view_settings
    vs.view_transform = 'Standard'
    vs.look = 'None'
    vs.exposure = 0.0
    vs.gamma = 1.0
    im = r.image_settings
    im.file_format = 'OPEN_EXR'
    im.color_depth = '32'
    im.color_mode = 'RGBA'
    im.exr_codec = 'ZIP'


def setup_render(scene, r, args, vols=()):
    check_keys(r, RENDER_KEYS, '[render]')
    if r.get('integrator', 'path') != 'path':
        fail(f"key 'integrator' in [render]: only \"path\" can be rendered with Cycles, got {r['integrator']!r}")
    if r.get('aovs', False):
        fail("key 'aovs' in [render]: AOV layers are not reproduced; set it false or drop it")
    width = args.width if args.width else integer(r.get('width', 320), 'render.width')
    height = args.height if args.height else integer(r.get('height', 240), 'render.height')
    spp = args.spp if args.spp else integer(r.get('spp', 64), 'render.spp')
    seed = args.seed if args.seed is not None else integer(r.get('seed', 0), 'render.seed')
    mb = integer(r.get('max_bounces', 256), 'render.max_bounces')
    if not (0 <= seed <= 2147483647):
        fail(f"key 'seed' in [render]: Cycles' seed is 0 ..= 2147483647, got {seed}")
    if mb < 0:
        fail(f"key 'max_bounces' in [render]: must be >= 0, got {mb}")
    if mb > 1025:
        fail(f"key 'max_bounces' in [render]: Cycles allows at most 1024 bounces "
             f"(max_bounces 1025), got {mb}")
    bounces = cycles_bounces(mb, vols)

    unbiased_cycles(scene, spp, seed, args.threads)
    cy = scene.cycles
    cy.max_bounces = bounces
    cy.volume_bounces = bounces
    cy.diffuse_bounces = bounces
    cy.glossy_bounces = bounces
    cy.transmission_bounces = bounces
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0
    if args.half:
        scene.render.image_settings.color_depth = '16'
    mblur = motion_blur(r)
    if mblur is not None:
        setup_motion_blur(scene, mblur)
    return dict(width=width, height=height, spp=spp, seed=seed, max_bounces=mb,
                cycles_bounces=bounces, motion_blur=mblur)


CAMERA_KEYS = ['position', 'look_at', 'up', 'vfov', 'focal_length', 'sensor_width',
               'sensor_height', 'sensor_fit', 'shift_x', 'shift_y', 'matrix', 'location',
               'rotation', 'framing', 'direction']
LENS_KEYS = ['focal_length', 'sensor_width', 'sensor_height', 'sensor_fit']
SENSOR_FITS = {'auto': 'AUTO', 'horizontal': 'HORIZONTAL', 'vertical': 'VERTICAL'}


def camera_pose(c):
    """The camera's world matrix (Blender's matrix_world: looks down local -Z,
    local +Y up) from position/look_at/up, matrix, or location + rotation."""
    groups = [('position/look_at/up', [k for k in ('position', 'look_at', 'up') if k in c]),
              ('matrix', [k for k in ('matrix',) if k in c]),
              ('location/rotation', [k for k in ('location', 'rotation') if k in c])]
    given = [(g, ks) for g, ks in groups if ks]
    if len(given) > 1:
        fail(f"key '{given[1][1][0]}' in [camera]: not together with '{given[0][1][0]}' "
             "(orient the camera by position/look_at/up, by matrix, or by location + rotation)")
    kind = given[0][0] if given else 'position/look_at/up'
    if kind == 'matrix':
        rows = c['matrix']
        if not isinstance(rows, list) or len(rows) != 4 or any(
                not isinstance(r, list) or len(r) != 4 for r in rows):
            fail("key 'matrix' in [camera]: expected 4 rows of 4 numbers (row-major, "
                 "Blender's camera matrix_world)")
        m = [[num(x, 'camera.matrix') for x in r] for r in rows]
        if m[3] != [0.0, 0.0, 0.0, 1.0]:
            fail("key 'matrix' in [camera]: the last row must be 0 0 0 1")
        cols = [Vector((m[0][j], m[1][j], m[2][j])) for j in range(3)]
        if min(v.length for v in cols) < 1e-12:
            fail("key 'matrix' in [camera]: a column of the 3 x 3 part is zero")
        # Scale is ignored, as Blender's view and Cycles (transform_clear_scale) do.
        cols = [v.normalized() for v in cols]
        if max(abs(cols[0].dot(cols[1])), abs(cols[0].dot(cols[2])),
               abs(cols[1].dot(cols[2]))) > 1e-4:
            fail("key 'matrix' in [camera]: the 3 x 3 part must be a rotation (times a "
                 "positive scale per axis); its columns are not orthogonal")
        if cols[0].cross(cols[1]).dot(cols[2]) <= 0:
            fail("key 'matrix' in [camera]: the 3 x 3 part is a reflection (determinant < 0)")
        return Matrix((
            (cols[0].x, cols[1].x, cols[2].x, m[0][3]),
            (cols[0].y, cols[1].y, cols[2].y, m[1][3]),
            (cols[0].z, cols[1].z, cols[2].z, m[2][3]),
            (0.0, 0.0, 0.0, 1.0)))
    if kind == 'location/rotation':
        if 'location' not in c:
            fail("missing key 'location' in [camera] (with 'rotation')")
        loc = Vector(vec3(c['location'], 'camera.location'))
        rot = Euler([math.radians(a) for a in vec3(c.get('rotation', [0.0, 0.0, 0.0]),
                                                     'camera.rotation')], 'XYZ')
        # Blender's object matrix: T * Rz * Ry * Rx (XYZ Euler).
        return Matrix.Translation(loc) @ rot.to_matrix().to_4x4()
    pos = Vector(vec3(c.get('position', [0.0, -4.5, 0.6]), 'camera.position'))
    at = Vector(vec3(c.get('look_at', [0.0, 0.0, 0.0]), 'camera.look_at'))
    up = Vector(vec3(c.get('up', [0.0, 0.0, 1.0]), 'camera.up'))
    f = at - pos
    if f.length == 0:
        fail("key 'look_at' in [camera]: must differ from position")
    f.normalize()
    right = f.cross(up)
    if right.length < 1e-9:
        fail("key 'up' in [camera]: must not be zero or parallel to look_at - position")
    right.normalize()
    u = right.cross(f)
    # Camera looks along its local -Z with +Y up.
    return Matrix((
        (right.x, u.x, -f.x, pos.x),
        (right.y, u.y, -f.y, pos.y),
        (right.z, u.z, -f.z, pos.z),
        (0, 0, 0, 1)))


def setup_camera(scene, c):
    check_keys(c, CAMERA_KEYS, '[camera]')
    if 'direction' in c and 'framing' not in c:
        fail("key 'direction' in [camera]: only used with framing = \"auto\"")
    if 'framing' in c:
        if c['framing'] != 'auto':
            fail(f"key 'framing' in [camera]: expected \"auto\", got {c['framing']!r}")
        fail("key 'framing' in [camera]: \"auto\" is vdbphoton's own choice of camera from the "
             "volumes' boxes; a reference needs the camera written out (give position/look_at/"
             "up and vfov, or matrix / location + rotation and focal_length)")
    cam = bpy.data.cameras.new('Cam')
    cam.type = 'PERSP'
    lens = [k for k in LENS_KEYS if k in c]
    if lens:
        if 'vfov' in c:
            fail(f"key '{lens[0]}' in [camera]: not together with 'vfov'")
        fl = num(c.get('focal_length', 50.0), 'camera.focal_length')
        sw = num(c.get('sensor_width', 36.0), 'camera.sensor_width')
        sh = num(c.get('sensor_height', 24.0), 'camera.sensor_height')
        # Blender's hard minimum is 1 mm for all three; below it Blender would
        # silently clamp the value.
        for k, x in (('focal_length', fl), ('sensor_width', sw), ('sensor_height', sh)):
            if not x >= 1.0:
                fail(f"key '{k}' in [camera]: Blender's minimum is 1 mm, got {x}")
        fit = c.get('sensor_fit', 'auto')
        if fit not in SENSOR_FITS:
            fail(f"key 'sensor_fit' in [camera]: expected \"auto\", \"horizontal\" or "
                 f"\"vertical\", got {fit!r}")
        cam.sensor_fit = SENSOR_FITS[fit]
        cam.sensor_width = sw
        cam.sensor_height = sh
        cam.lens = fl
    else:
        vfov = num(c.get('vfov', 40.0), 'camera.vfov')
        if not (0 < vfov < 180):
            fail(f"key 'vfov' in [camera]: must be in (0, 180), got {vfov}")
        cam.sensor_fit = 'VERTICAL'
        cam.angle_y = math.radians(vfov)
    cam.shift_x = num(c.get('shift_x', 0.0), 'camera.shift_x')
    cam.shift_y = num(c.get('shift_y', 0.0), 'camera.shift_y')
    cam.clip_start = 1e-4
    cam.clip_end = 1e6
    camo = bpy.data.objects.new('Cam', cam)
    scene.collection.objects.link(camo)
    camo.matrix_world = camera_pose(c)
    scene.camera = camo


def track_minus_z(direction):
    """Rotation that points an object's local -Z along `direction`."""
    return Vector(direction).normalized().to_track_quat('-Z', 'Y')


def setup_lights(scene, lights):
    if not isinstance(lights, list):
        fail("'light' must be an array of tables ([[light]])")
    for i, L in enumerate(lights):
        where = f'[[light]] #{i + 1}'
        if not isinstance(L, dict) or 'type' not in L:
            fail(f"missing key 'type' in {where}")
        t = L['type']
        keys = {'sun': ['type', 'direction', 'irradiance', 'angle'],
                'point': ['type', 'position', 'intensity'],
                'spot': ['type', 'position', 'direction', 'intensity', 'cone_angle',
                         'blend', 'cone_falloff']}
        if t not in keys:
            fail(f"key 'type' in {where}: expected sun, point or spot, got {t!r}")
        check_keys(L, keys[t], f'{where} (type = "{t}")')
        ld = bpy.data.lights.new(f'L{i}', type=t.upper())
        lo = bpy.data.objects.new(f'L{i}', ld)
        scene.collection.objects.link(lo)
        lo.rotation_mode = 'QUATERNION'
        ld.use_temperature = False
        ld.exposure = 0.0
        if t == 'sun':
            for k in ('direction', 'irradiance'):
                if k not in L:
                    fail(f"missing key '{k}' in {where}")
            d = vec3(L['direction'], 'light.direction')
            if Vector(d).length == 0:
                fail(f"key 'direction' in {where}: must not be zero")
            col, e = split_rgb(nonneg_rgb(L['irradiance'], 'light.irradiance'))
            ld.color = col
            ld.energy = e
            angle = num(L.get('angle', 0.0), 'light.angle')
            if not (0 <= angle < 180):
                fail(f"key 'angle' in {where}: must be in [0, 180), got {angle}")
            ld.angle = math.radians(angle)
            # Blender's sun shines along its local -Z; `direction` points to the sun.
            lo.rotation_quaternion = track_minus_z([-x for x in d])
        else:
            for k in ('position', 'intensity') + (('direction',) if t == 'spot' else ()):
                if k not in L:
                    fail(f"missing key '{k}' in {where}")
            lo.location = Vector(vec3(L['position'], 'light.position'))
            col, inten = split_rgb(nonneg_rgb(L['intensity'], 'light.intensity'))
            ld.color = col
            ld.energy = 4.0 * math.pi * inten  # Blender Power P = 4 pi I, spots too
            ld.shadow_soft_size = 0.0
            ld.use_soft_falloff = False
            if t == 'spot':
                d = vec3(L['direction'], 'light.direction')
                if Vector(d).length == 0:
                    fail(f"key 'direction' in {where}: must not be zero")
                cone = num(L.get('cone_angle', 45.0), 'light.cone_angle')
                if not (0 < cone <= 180):
                    fail(f"key 'cone_angle' in {where}: must be in (0, 180], got {cone}")
                if 'blend' in L and 'cone_falloff' in L:
                    fail(f"keys 'blend' and 'cone_falloff' in {where}: give only one")
                blend = num(L.get('blend', L.get('cone_falloff', 0.15)), 'light.blend')
                if not (0 <= blend <= 1):
                    fail(f"key 'blend' in {where}: must be in [0, 1], got {blend}")
                ld.spot_size = math.radians(cone)
                ld.spot_blend = blend
                ld.show_cone = False
                lo.rotation_quaternion = track_minus_z(d)


def setup_world(scene, env, base):
    check_keys(env, ['radiance', 'map', 'strength', 'rotate_z'], '[environment]')
    world = bpy.data.worlds.new('World')
    world.use_nodes = True
    nt = world.node_tree
    bg = nt.nodes['Background']
    if 'map' in env:
        if 'radiance' in env:
            fail("key 'radiance' in [environment]: not together with 'map'")
        strength = num(env.get('strength', 1.0), 'environment.strength')
        rot = num(env.get('rotate_z', 0.0), 'environment.rotate_z')
        path = resolve(base, env['map'])
        if not os.path.exists(path):
            fail(f"key 'map' in [environment]: cannot read {path}")
        img = bpy.data.images.load(path)
        img.colorspace_settings.name = 'Non-Color'  # linear values as stored
        tex = nt.nodes.new('ShaderNodeTexEnvironment')
        tex.image = img
        tex.projection = 'EQUIRECTANGULAR'
        tex.interpolation = 'Closest'
        tc = nt.nodes.new('ShaderNodeTexCoord')
        mp = nt.nodes.new('ShaderNodeMapping')
        mp.vector_type = 'POINT'
        # vdbphoton looks up the map at the world direction rotated by -rotate_z.
        mp.inputs['Rotation'].default_value = (0.0, 0.0, -math.radians(rot))
        nt.links.new(tc.outputs['Generated'], mp.inputs['Vector'])
        nt.links.new(mp.outputs['Vector'], tex.inputs['Vector'])
        nt.links.new(tex.outputs['Color'], bg.inputs['Color'])
        bg.inputs['Strength'].default_value = strength
    else:
        for k in ('strength', 'rotate_z'):
            if k in env:
                fail(f"key '{k}' in [environment]: only with 'map'")
        c = nonneg_rgb(env.get('radiance', 0.0), 'environment.radiance')
        bg.inputs['Color'].default_value = (c[0], c[1], c[2], 1.0)
        bg.inputs['Strength'].default_value = 1.0
    scene.world = world


PRINCIPLED_KEYS = ['density', 'color', 'absorption_color', 'anisotropy', 'emission_strength',
                   'emission_color', 'blackbody_intensity', 'blackbody_tint', 'temperature']
RAW_KEYS = ['sigma_s', 'sigma_a', 'emission', 'phase']


def new_material(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    m.cycles.volume_interpolation = 'LINEAR'
    return m, nt


def attribute(nt, name):
    a = nt.nodes.new('ShaderNodeAttribute')
    a.attribute_type = 'GEOMETRY'
    a.attribute_name = name
    return a.outputs['Factor']


def times(nt, socket, k):
    """socket * k (a Math node)."""
    n = nt.nodes.new('ShaderNodeMath')
    n.operation = 'MULTIPLY'
    n.use_clamp = False
    nt.links.new(socket, n.inputs[0])
    n.inputs[1].default_value = k
    return n.outputs['Value']


def clamp0(nt, socket):
    n = nt.nodes.new('ShaderNodeMath')
    n.operation = 'MAXIMUM'
    nt.links.new(socket, n.inputs[0])
    n.inputs[1].default_value = 0.0
    return n.outputs['Value']


def principled_material(nt, mat, v, where, notes):
    pv = nt.nodes.new('ShaderNodeVolumePrincipled')
    # A volume naming a temperature or flame grid gets Blender's Quick Smoke
    # values for the keys it leaves out (Density 5, Blackbody Intensity 1), as
    # in vdbphoton.
    smoke = 'temperature_grid' in v or 'flame_grid' in v
    d = num(mat.get('density', 5.0 if smoke else 1.0), 'material.density')
    col = nonneg_rgb(mat.get('color', 0.5), 'material.color')
    ac = nonneg_rgb(mat.get('absorption_color', 0.0), 'material.absorption_color')
    g = num(mat.get('anisotropy', 0.0), 'material.anisotropy')
    es = num(mat.get('emission_strength', 0.0), 'material.emission_strength')
    ec = nonneg_rgb(mat.get('emission_color', 1.0), 'material.emission_color')
    bi = num(mat.get('blackbody_intensity', 1.0 if smoke else 0.0),
             'material.blackbody_intensity')
    bt = nonneg_rgb(mat.get('blackbody_tint', 1.0), 'material.blackbody_tint')
    temp = num(mat.get('temperature', 1000.0), 'material.temperature')
    for k, x in (('density', d), ('emission_strength', es), ('blackbody_intensity', bi),
                 ('temperature', temp)):
        if x < 0:
            fail(f"key '{k}' in {where}.material: must be >= 0, got {x}")
    if not (-1 <= g <= 1):
        fail(f"key 'anisotropy' in {where}.material: must be in [-1, 1], got {g}")
    pv.inputs['Density'].default_value = d
    pv.inputs['Density Attribute'].default_value = v.get('density_grid', 'density')
    pv.inputs['Color'].default_value = (*col, 1.0)
    pv.inputs['Color Attribute'].default_value = v.get('color_grid', '') or ''
    pv.inputs['Absorption Color'].default_value = (*ac, 1.0)
    pv.inputs['Anisotropy'].default_value = g
    pv.inputs['Emission Color'].default_value = (*ec, 1.0)
    pv.inputs['Blackbody Intensity'].default_value = bi
    pv.inputs['Blackbody Tint'].default_value = (*bt, 1.0)
    pv.inputs['Temperature'].default_value = temp
    # Empty name: the attribute is not found and Cycles uses Temperature as is
    # (vdbphoton without a temperature_grid does the same).
    pv.inputs['Temperature Attribute'].default_value = v.get('temperature_grid', '') or ''
    if 'temperature_from_flame' in v:
        # Blender's fluid domain temperature, ignition + flame (max - ignition)
        # where flame > 0.01, else 0, is made per voxel. A Volume object can
        # only get it through shader nodes on an Attribute node, and Cycles
        # interpolates an Attribute node's grid trilinearly (the Principled
        # Volume's own Temperature Attribute lookup takes one voxel at a
        # time): measured on the Blender smoke frame 25, emission only, the
        # nodes give R +6 %, G -6 %, B -24 % against the same mapping stored
        # per voxel, and an Attribute node reading a temperature grid gives
        # 0.81 / 0.78 / 0.74 of the Principled lookup.
        fail(f"key 'temperature_from_flame' in {where}: Cycles cannot make Blender's fluid "
             "domain temperature from a Volume object's flame grid (shader nodes see the "
             "flame interpolated between voxels, Blender maps each voxel: R +6 %, B -24 % "
             "on the Blender smoke frame 25); render the .blend itself with "
             "tools/blender/test_export/render_blend.py, or store the temperature as a grid "
             "(ignition + flame x (max_temp - ignition) where flame > 0.01, else 0) and name "
             "it in temperature_grid")
    if 'flame_grid' in v and es > 0:
        nt.links.new(times(nt, clamp0(nt, attribute(nt, v['flame_grid'])), es),
                     pv.inputs['Emission Strength'])
    else:
        pv.inputs['Emission Strength'].default_value = es
    if es > 0 and max(ec) > 0:
        notes.append(f'{where}: Emission Strength > 0: vdbphoton emits it only where the density '
                     'is > 0, Cycles wherever its volume mesh is')
    if bi > 0 and 'temperature_grid' not in v:
        notes.append(f'{where}: blackbody without temperature_grid: vdbphoton emits it only '
                     'where the density is > 0, Cycles wherever its volume mesh is')
    return pv.outputs['Volume']


def add_shaders(nt, shaders):
    out = shaders[0]
    for s in shaders[1:]:
        a = nt.nodes.new('ShaderNodeAddShader')
        nt.links.new(out, a.inputs[0])
        nt.links.new(s, a.inputs[1])
        out = a.outputs['Shader']
    return out


def raw_material(nt, mat, v, where, notes):
    ss = nonneg_rgb(mat.get('sigma_s', 0.0), 'material.sigma_s')
    sa = nonneg_rgb(mat.get('sigma_a', 0.0), 'material.sigma_a')
    em = nonneg_rgb(mat.get('emission', 0.0), 'material.emission')
    ph = mat.get('phase', {'type': 'isotropic'})
    if not isinstance(ph, dict) or 'type' not in ph:
        fail(f"key 'phase' in {where}.material: expected a table with a 'type'")
    pt = ph['type']
    if pt == 'isotropic':
        check_keys(ph, ['type'], f'{where}.material.phase (isotropic)')
        lobes = [(0.0, 1.0)]
    elif pt == 'hg':
        check_keys(ph, ['type', 'g'], f'{where}.material.phase (hg)')
        if 'g' not in ph:
            fail(f"missing key 'g' in {where}.material.phase")
        lobes = [(num(ph['g'], 'material.phase.g'), 1.0)]
    elif pt == 'hg_mix':
        check_keys(ph, ['type', 'lobes'], f'{where}.material.phase (hg_mix)')
        ls = ph.get('lobes')
        if not isinstance(ls, list) or not ls:
            fail(f"key 'phase.lobes' in {where}.material: expected a non-empty array")
        lobes = []
        for j, lb in enumerate(ls):
            check_keys(lb, ['g', 'weight'], f'{where}.material.phase.lobes[{j}]')
            lobes.append((num(lb['g'], f'material.phase.lobes[{j}].g'),
                          num(lb['weight'], f'material.phase.lobes[{j}].weight')))
        if min(w for _, w in lobes) < 0 or sum(w for _, w in lobes) <= 0:
            fail(f"key 'phase.lobes' in {where}.material: weights must be >= 0 with a positive sum")
        tot = sum(w for _, w in lobes)
        lobes = [(g, w / tot) for g, w in lobes if w > 0]
    elif pt == 'schlick':
        fail(f"key 'phase.type' in {where}.material: Cycles has no Schlick phase function "
             "(use \"hg\" with the same g)")
    else:
        fail(f"key 'phase.type' in {where}.material: unknown phase {pt!r}")
    for g, _ in lobes:
        if not (-1 <= g <= 1):
            fail(f"key 'phase.g' in {where}.material: must be in [-1, 1], got {g}")
    for k in ('color_grid', 'flame_grid', 'temperature_grid', 'temperature_from_flame'):
        if k in v:
            notes.append(f'{where}: {k} is ignored with raw coefficients (by vdbphoton too)')
    dens = clamp0(nt, attribute(nt, v.get('density_grid', 'density')))
    shaders = []
    col, m = split_rgb(ss)
    if m > 0:
        for g, w in lobes:
            n = nt.nodes.new('ShaderNodeVolumeScatter')
            n.phase = 'HENYEY_GREENSTEIN'
            n.inputs['Color'].default_value = (*col, 1.0)
            n.inputs['Anisotropy'].default_value = g
            nt.links.new(times(nt, dens, m * w), n.inputs['Density'])
            shaders.append(n.outputs['Volume'])
    col, m = split_rgb(sa)
    if m > 0:
        n = nt.nodes.new('ShaderNodeVolumeAbsorption')
        n.inputs['Color'].default_value = (1 - col[0], 1 - col[1], 1 - col[2], 1.0)
        nt.links.new(times(nt, dens, m), n.inputs['Density'])
        shaders.append(n.outputs['Volume'])
    col, m = split_rgb(em)
    if m > 0:
        n = nt.nodes.new('ShaderNodeEmission')
        n.inputs['Color'].default_value = (*col, 1.0)
        nt.links.new(times(nt, dens, m), n.inputs['Strength'])
        shaders.append(n.outputs['Emission'])
    if not shaders:
        return None
    return add_shaders(nt, shaders)


def check_bounds(v, where):
    """`bounds` only steers vdbphoton's automatic framing; checked, not used."""
    b = v['bounds']
    if b in ('active', 'sequence', 'domain'):
        return
    if not isinstance(b, list) or len(b) != 2:
        fail(f"key 'bounds' in {where}: expected \"active\", \"sequence\", \"domain\" or "
             "[[x0, y0, z0], [x1, y1, z1]]")
    lo, hi = vec3(b[0], 'volume.bounds'), vec3(b[1], 'volume.bounds')
    if any(a > c for a, c in zip(lo, hi)):
        fail(f"key 'bounds' in {where}: the first corner must be <= the second in x, y and z")


def setup_velocity(vol, v, where, names, mblur, path):
    """The Volume's velocity grid, scale and unit (Blender's Volume data
    settings), as vdbphoton reads them: `velocity_grid` (default: the first
    of velocity, vel the file has), `velocity_scale` (one number; Cycles
    has no per-axis scale), `velocity_unit` second | frame."""
    unit = v.get('velocity_unit', 'second')
    if unit not in ('second', 'frame'):
        fail(f"key 'velocity_unit' in {where}: expected \"second\" or \"frame\", got {unit!r}")
    scale = v.get('velocity_scale', 1.0)
    if isinstance(scale, list):
        sc = vec3(scale, 'velocity_scale')
        if not (sc[0] == sc[1] == sc[2]):
            fail(f"key 'velocity_scale' in {where}: Cycles scales velocities by one number; "
                 f"a per-axis scale {sc} cannot be reproduced")
        scale = sc[0]
    scale = num(scale, 'velocity_scale')
    if mblur is None:
        return
    name = v.get('velocity_grid')
    if name is None:
        name = next((n for n in ('velocity', 'vel') if n in names
                     or all(f'{n}{c}' in names for c in ('.x', '.y', '.z'))), None)
        if name is None:
            return
    elif name not in names and not all(f'{name}{c}' in names for c in ('.x', '.y', '.z')):
        raise FrameError(f"key 'velocity_grid' in {where}: no grid '{name}' in {path} "
                         f"(grids: {', '.join(names)})")
    vol.velocity_grid = name
    vol.velocity_unit = 'SECOND' if unit == 'second' else 'FRAME'
    if unit == 'frame':
        # Cycles ignores the shutter for velocities per frame.
        scale *= mblur['shutter']
    if scale < 0.0:
        fail(f"key 'velocity_scale' in {where}: Cycles clamps a negative Velocity Scale at 0")
    vol.velocity_scale = scale


def setup_volume(scene, i, v, base, notes, frame, mblur=None):
    where = f'[[volume]] #{i + 1}'
    check_keys(v, ['file', 'density_grid', 'temperature_grid', 'flame_grid', 'color_grid',
                   'blackbody_interpolation', 'transform', 'material', 'bounds', 'frame_offset',
                   'temperature_from_flame', 'velocity_grid', 'velocity_scale',
                   'velocity_unit'], where)
    if 'file' not in v:
        fail(f"missing key 'file' in {where}")
    if not isinstance(v['file'], str):
        fail(f"key 'file' in {where}: expected a path, got {v['file']!r}")
    if 'bounds' in v:
        check_bounds(v, where)
    offset = integer(v.get('frame_offset', 0), 'frame_offset')
    if abs(offset) > MAX_FRAME:
        fail(f"key 'frame_offset' in {where}: must be within +-{MAX_FRAME}, got {offset}")
    bi = v.get('blackbody_interpolation', 'emission')
    if bi not in ('emission', 'temperature'):
        fail(f"key 'blackbody_interpolation' in {where}: expected \"emission\" or "
             f"\"temperature\", got {bi!r}")
    if bi == 'temperature' and 'temperature_grid' in v:
        notes.append(f'{where}: blackbody_interpolation = "temperature": Cycles evaluates the '
                     'blackbody per voxel (its stochastic one-tap lookup), as vdbphoton\'s '
                     '"emission"; fire differs')
    file_frame = frame
    if frame is not None and has_frame_pattern(v['file']):
        file_frame = frame + offset
        if file_frame < 0:
            raise FrameError(f"key 'frame_offset' in {where}: frame {frame} with frame_offset "
                             f"{offset} is before frame 0")
    path = resolve(base, with_frame(v['file'], file_frame))
    if not os.path.isfile(path):
        what = 'no such file' if not os.path.exists(path) else 'not a file'
        raise FrameError(f"key 'file' in {where}: {what}: {path}")
    vol = bpy.data.volumes.new(f'vol{i}')
    vol.filepath = path
    vol.render.precision = 'FULL'
    vol.render.clipping = 0.0
    # Densities per world length, as vdbphoton's: with Blender's default
    # Space = Object, Cycles divides them by the object's scale
    # (object_volume_density: x 1 / |M (1,1,1)/sqrt 3|).
    vol.render.space = 'WORLD'
    vo = bpy.data.objects.new(f'vol{i}', vol)
    scene.collection.objects.link(vo)
    vol.grids.load()
    names = [g.name for g in vol.grids]
    if not names:
        err = vol.grids.error_message or 'no grids'
        raise FrameError(f"key 'file' in {where}: Blender cannot read {path}: {err}")
    for k in ('density_grid', 'temperature_grid', 'flame_grid', 'color_grid'):
        name = v.get(k, 'density' if k == 'density_grid' else None)
        if name is not None and name not in names:
            raise FrameError(f"key '{k}' in {where}: no grid '{name}' in {path} "
                             f"(grids: {', '.join(names)})")
    setup_velocity(vol, v, where, names, mblur, path)

    tr = v.get('transform', {})
    check_keys(tr, ['translate', 'rotate', 'scale', 'matrix'], f'{where}.transform')
    if 'matrix' in tr:
        if len(tr) > 1:
            fail(f"key 'matrix' in {where}.transform: not together with translate/rotate/scale")
        rows = tr['matrix']
        if not isinstance(rows, list) or len(rows) != 4 or any(
                not isinstance(r, list) or len(r) != 4 for r in rows):
            fail(f"key 'matrix' in {where}.transform: expected 4 rows of 4 numbers")
        m = [[num(x, 'transform.matrix') for x in r] for r in rows]
        if m[3] != [0.0, 0.0, 0.0, 1.0]:
            fail(f"key 'matrix' in {where}.transform: the last row must be 0 0 0 1")
        M = Matrix(m)
        if abs(M.determinant()) < 1e-300:
            fail(f"key 'matrix' in {where}.transform: not invertible")
        vo.matrix_world = M
    else:
        vo.location = vec3(tr.get('translate', [0, 0, 0]), 'transform.translate')
        vo.rotation_mode = 'XYZ'
        vo.rotation_euler = [math.radians(a) for a in vec3(tr.get('rotate', [0, 0, 0]),
                                                             'transform.rotate')]
        s = rgb(tr.get('scale', 1.0), 'transform.scale')
        if 0.0 in s:
            fail(f"key 'scale' in {where}.transform: no zero component")
        vo.scale = s

    mat = v.get('material', {})
    check_keys(mat, PRINCIPLED_KEYS + RAW_KEYS, f'{where}.material')
    pk = [k for k in mat if k in PRINCIPLED_KEYS]
    rk = [k for k in mat if k in RAW_KEYS]
    if pk and rk:
        fail(f"key '{rk[0]}' in {where}.material: raw keys cannot be mixed with Principled "
             f"keys ('{pk[0]}')")
    m, nt = new_material(f'vol{i}')
    shader = (raw_material if rk else principled_material)(nt, mat, v, where, notes)
    if shader is not None:
        o = nt.nodes.new('ShaderNodeOutputMaterial')
        o.target = 'CYCLES'
        nt.links.new(shader, o.inputs['Volume'])
    vo.data.materials.append(m)
    return path, names


# --------------------------------------------------------------------- main

def build_scene(desc, args, base, frame, notes):
    """A fresh Blender scene for one frame (None: a scene without frames)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if frame is not None:
        scene.frame_set(frame)
    vols = desc.get('volume', [])
    info = setup_render(scene, desc.get('render', {}), args,
                        vols if isinstance(vols, list) else [])
    setup_camera(scene, desc.get('camera', {}))
    setup_lights(scene, desc.get('light', []))
    setup_world(scene, desc.get('environment', {}), base)
    if not isinstance(vols, list) or not vols:
        fail('no [[volume]]: a scene needs at least one volume')
    paths = []
    for i, v in enumerate(vols):
        path, grids = setup_volume(scene, i, v, base, notes, frame, info['motion_blur'])
        paths.append((path, grids))
    return scene, info, paths


def frame_list(desc, args):
    """The frames to render: --frame, --frames, [render] frames, or [None]."""
    if args.frame is not None and args.frames is not None:
        fail('give --frame or --frames, not both')
    if args.frame is not None:
        if not 0 <= args.frame <= MAX_FRAME:
            fail(f'--frame: expected a frame number in 0 ..= {MAX_FRAME}, got {args.frame}')
        return [args.frame]
    if args.frames is not None:
        return parse_frames(args.frames, '--frames')
    r = desc.get('render', {})
    if isinstance(r, dict) and 'frames' in r:
        return parse_frames(r['frames'], "key 'frames' in [render]")
    return None


def save_exr(scene, out):
    """Writes the render result to `out` through a temporary name."""
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmp = os.path.join(os.path.dirname(out), f'.{os.path.basename(out)}.{os.getpid()}.tmp.exr')
    try:
        bpy.data.images['Render Result'].save_render(filepath=tmp, scene=scene)
        if not os.path.isfile(tmp):
            raise OSError(f'Blender wrote no file {tmp}')
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('out', nargs='?',
                    help="output EXR (may hold {frame}, {frame:04} or ####); default: the "
                         "scene's [render] output")
    ap.add_argument('--spp', type=int)
    ap.add_argument('--seed', type=int)
    ap.add_argument('--width', type=int)
    ap.add_argument('--height', type=int)
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--frames', help="frame list: '1-40', '1-3,5,7-20:2'")
    ap.add_argument('--frame', type=int, help='render this one frame')
    ap.add_argument('--skip-existing', action='store_true',
                    help='skip a frame whose output EXR exists')
    ap.add_argument('--half', action='store_true', help='write half-float EXRs (float32 otherwise)')
    args = ap.parse_args(argv)
    scene_path = os.path.abspath(args.scene)
    base = os.path.dirname(scene_path)
    name = os.path.basename(scene_path)
    try:
        desc = load_scene(scene_path)
    except (OSError, ValueError) as e:
        print(f'{name}: {e}', file=sys.stderr)
        return 2

    try:
        check_keys(desc, ['render', 'camera', 'light', 'environment', 'volume'], 'the scene')
        r = desc.get('render', {})
        check_keys(r, RENDER_KEYS, '[render]')
        if args.out is not None:
            out_pattern = os.path.abspath(args.out)
        else:
            o = r.get('output', 'out.exr')
            if not isinstance(o, str):
                fail(f"key 'output' in [render]: expected a path, got {o!r}")
            out_pattern = resolve(base, o)
        if not out_pattern.lower().endswith('.exr'):
            fail(f'output {out_pattern}: the name must end in .exr')
        check_frame_pattern(out_pattern, 'output')
        vols = desc.get('volume', [])
        patterned = []
        if isinstance(vols, list):
            for i, v in enumerate(vols):
                if isinstance(v, dict) and isinstance(v.get('file'), str):
                    check_frame_pattern(v['file'], f'file in [[volume]] #{i + 1}')
                    if has_frame_pattern(v['file']):
                        patterned.append(v['file'])
        frames = frame_list(desc, args)
        if frames is None:
            if patterned or has_frame_pattern(out_pattern):
                what = patterned[0] if patterned else out_pattern
                fail(f'{what!r} holds a frame pattern but no frames are given (use --frames, '
                     "--frame or [render] frames)")
            frames = [None]
        elif len(frames) > 1 and not has_frame_pattern(out_pattern):
            fail(f'{len(frames)} frames would all be written to {out_pattern}: put {{frame:04}} '
                 'or #### in the output name')
    except SceneError as e:
        print(f'{name}: {e}', file=sys.stderr)
        return 2

    failed = []
    for frame in frames:
        tag = '' if frame is None else f'frame {frame}: '
        out = with_frame(out_pattern, frame)
        if args.skip_existing and os.path.exists(out):
            print(f'{tag}skipped, {out} exists', file=sys.stderr)
            continue
        notes = []
        t_frame = time.time()
        try:
            scene, info, paths = build_scene(desc, args, base, frame, notes)
        except FrameError as e:
            print(f'{name}: {tag}{e}', file=sys.stderr, flush=True)
            if frame is None:
                return 2
            failed.append(frame)
            continue
        except SceneError as e:
            print(f'{name}: {tag}{e}', file=sys.stderr)
            return 2
        for i, (path, grids) in enumerate(paths):
            print(f'{tag}volume {i + 1}: {path} grids {grids}')
        for n in notes:
            print('note:', n)
        print(f"{tag}SAMPLES {info['spp']} SEED {info['seed']} SIZE {info['width']}x{info['height']} "
              f"MAX_BOUNCES {info['max_bounces']} (Cycles bounces {info['cycles_bounces']}) "
              f"THREADS {scene.render.threads}", flush=True)
        t0 = time.time()
        bpy.ops.render.render(write_still=False)
        t1 = time.time()
        try:
            save_exr(scene, out)
        except OSError as e:
            print(f'{name}: {tag}cannot write {out}: {e}', file=sys.stderr, flush=True)
            failed.append(frame)
            continue
        print(f'{tag}RENDER_TIME {t1 - t0:.2f} s -> {out}')
        print(f"Saved: '{out}'", flush=True)
        if frame is not None:
            print(f'frame {frame}: {time.time() - t_frame:.2f} s', file=sys.stderr, flush=True)
    print(f'TOTAL_WALL {time.time() - T_START:.2f} s')
    if failed:
        print(f"{name}: {len(failed)} of {len(frames)} frames failed: "
              f"{', '.join(str(f) for f in failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
