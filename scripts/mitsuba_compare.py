#!/usr/bin/env python3
"""Render a vdbphoton scene with Mitsuba 3 as an independent reference, render
it with vdbphoton, and compare the two images with `vdbphoton compare`.

Usage (from anywhere; paths inside the TOML are relative to the TOML file):

    /tmp/mi-venv/bin/python scripts/mitsuba_compare.py SCENE.toml \
        [--spp-mitsuba 256] [--spp-vdbphoton 256] [--out DIR] [--delta-sun]

Writes DIR/density.vol (the dense grid), DIR/mitsuba.exr, DIR/vdbphoton.exr
(and DIR/vdbphoton.png, the preview, so the scene's own preview path is not
touched) and prints the Mitsuba render time, the vdbphoton wall time and the
line printed by `vdbphoton compare DIR/vdbphoton.exr DIR/mitsuba.exr`
(the Mitsuba image is the reference). DIR defaults to out/mitsuba_compare in
the repository (git-ignored).

Set-up on Debian 12 (from a clean checkout):

    apt-get update && apt-get install -y libllvm19 python3-venv
    python3 -m venv /tmp/mi-venv
    /tmp/mi-venv/bin/pip install mitsuba==3.9.1      # pulls drjit 1.5.0
    cargo build --release                            # target/release/vdbphoton

Mitsuba's CPU variant `llvm_ad_rgb` JIT-compiles through libLLVM; with Debian's
libLLVM 14 or 15 its first kernel aborts, so LLVM 19 is required. If Dr.Jit
does not pick it up by itself, the script sets DRJIT_LIBLLVM_PATH to Debian's
/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 (see `dpkg -L libllvm19`) when that
file exists; you can also set the variable yourself.

The Mitsuba scene reproduces the set-up of data/reference/README.md:
integrator `volpath` with max_depth = max_bounces + 1 (Mitsuba counts the
camera segment) and rr_depth = max_depth (no Russian roulette); a
`heterogeneous` medium with sigma_t = gridvolume (trilinear, clamp) x scale,
a constant albedo and an `hg`/`isotropic` phase; the grid is exported by
`vdbphoton export-vol` (the active box padded by one zero voxel). Mitsuba's
gridvolume ignores the .vol header's box unless asked and maps the data to the
unit cube of its `to_world`, with texel centres at (i + 0.5) / res
(src/volumes/grid.cpp: `p = fmadd(p, res, -0.5)` before the lookup); since the
header's box spans the cells' outer faces (index lo - 0.5 .. hi + 0.5), mapping
the unit cube onto that box puts every cell centre on its OpenVDB voxel
centre. The medium's boundary is a `cube` with a `null` BSDF exactly around
that box. Sun = `directional` (irradiance; Mitsuba's direction is the
direction of travel, minus the scene's), environment = `constant`, camera
`perspective` with fov_axis y, film `hdrfilm` float32 RGB with a box filter
and no border sampling, sampler `independent`. Mitsuba renders in passes (at
most --max-lanes samples each, different seeds) that are averaged.

Supported scene content: one [[volume]] (file, density_grid, transform with
`translate` only, Principled material without emission or raw sigma_s/sigma_a
with an isotropic or hg phase); extinction must be grey (the same in R, G, B)
because Mitsuba's `scale` is a single number; [[light]] of type "sun" with
angle 0 (a finite sun is refused unless --delta-sun, which renders BOTH images
with angle 0: vdbphoton then renders a JSON copy of the scene, DIR/scene.json);
[environment] radiance; [camera]; [render] width/height/max_bounces (spp, seed,
output and preview are overridden or ignored). The camera must be outside the
volume's box. Anything else stops the script with a message naming the key.
"""

import argparse
import copy
import glob
import json
import math
import os
import struct
import subprocess
import sys
import time
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


class Unsupported(Exception):
    pass


# ---------------------------------------------------------------- scene parsing

def rgb(value, key):
    """A colour: a number (grey) or [r, g, b]."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [float(value)] * 3
    if isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return [float(v) for v in value]
    raise Unsupported(f"key '{key}': expected a number or [r, g, b], got {value!r}")


def vec3(value, key):
    if isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return [float(v) for v in value]
    raise Unsupported(f"key '{key}': expected [x, y, z], got {value!r}")


def check_keys(table, allowed, where):
    for k in table:
        if k not in allowed:
            raise Unsupported(f"key '{k}' in {where} is not supported by this script "
                              f"(supported: {', '.join(sorted(allowed))})")


def normalize(v):
    n = math.sqrt(sum(x * x for x in v))
    if n == 0:
        raise Unsupported("zero-length direction")
    return [x / n for x in v]


def material_coefficients(mat):
    """(sigma_s, sigma_a, phase) per unit of grid density, the way vdbphoton
    and Cycles read the material table. phase = ('isotropic',) or ('hg', g)."""
    principled = {"density", "color", "absorption_color", "anisotropy",
                  "emission_strength", "emission_color", "blackbody_intensity",
                  "blackbody_tint", "temperature"}
    raw = {"sigma_s", "sigma_a", "emission", "phase"}
    for k in mat:
        if k not in principled | raw:
            raise Unsupported(f"unknown key '{k}' in [volume.material]")
    if set(mat) & raw and set(mat) & principled:
        raise Unsupported("[volume.material] mixes Principled and raw keys")
    if set(mat) & raw:
        if any(c != 0 for c in rgb(mat.get("emission", 0.0), "emission")):
            raise Unsupported("key 'emission' in [volume.material]: emission is not supported")
        ss = rgb(mat.get("sigma_s", 0.0), "sigma_s")
        sa = rgb(mat.get("sigma_a", 0.0), "sigma_a")
        ph = mat.get("phase", {"type": "isotropic"})
        if not isinstance(ph, dict):
            raise Unsupported("key 'phase' in [volume.material] must be a table")
        t = ph.get("type")
        if t == "isotropic":
            check_keys(ph, {"type"}, "[volume.material.phase] (isotropic)")
            phase = ("isotropic",)
        elif t == "hg":
            check_keys(ph, {"type", "g"}, "[volume.material.phase] (hg)")
            phase = ("hg", float(ph["g"]))
        else:
            raise Unsupported(f"key 'phase.type' = {t!r} in [volume.material] is not "
                              "supported (only \"isotropic\" and \"hg\")")
        return ss, sa, phase
    # Principled Volume (Cycles svm_node_principled_volume):
    # sigma_s = D*C, sigma_a = D*max(1-C,0)*max(1-sqrt(A),0), HG(anisotropy).
    if float(mat.get("emission_strength", 0.0)) > 0:
        raise Unsupported("key 'emission_strength' in [volume.material]: emission is not supported")
    if float(mat.get("blackbody_intensity", 0.0)) > 0:
        raise Unsupported("key 'blackbody_intensity' in [volume.material]: emission is not supported")
    d = float(mat.get("density", 1.0))
    c = rgb(mat.get("color", [0.5, 0.5, 0.5]), "color")
    a = rgb(mat.get("absorption_color", [0.0, 0.0, 0.0]), "absorption_color")
    ss = [d * ci for ci in c]
    sa = [d * max(1.0 - ci, 0.0) * max(1.0 - math.sqrt(ai), 0.0) for ci, ai in zip(c, a)]
    g = float(mat.get("anisotropy", 0.0))
    return ss, sa, (("hg", g) if g != 0.0 else ("isotropic",))


def parse_scene(path, delta_sun):
    with open(path, "rb") as f:
        scene = tomllib.load(f)
    base = path.parent
    check_keys(scene, {"render", "camera", "light", "environment", "volume"}, "the scene")

    r = scene.get("render", {})
    check_keys(r, {"width", "height", "spp", "seed", "max_bounces", "integrator",
                   "output", "preview", "exposure", "aovs"}, "[render]")
    if r.get("integrator", "path") != "path":
        raise Unsupported(f"key 'integrator' in [render] = {r['integrator']!r} (only \"path\")")
    if r.get("aovs", False):
        raise Unsupported("key 'aovs' in [render] = true is not supported")
    out = {
        "width": int(r.get("width", 320)),
        "height": int(r.get("height", 240)),
        "max_bounces": int(r.get("max_bounces", 256)),
    }

    c = scene.get("camera", {})
    check_keys(c, {"position", "look_at", "up", "vfov"}, "[camera]")
    out["camera"] = {
        "position": vec3(c.get("position", [0.0, -4.5, 0.6]), "camera.position"),
        "look_at": vec3(c.get("look_at", [0.0, 0.0, 0.0]), "camera.look_at"),
        "up": vec3(c.get("up", [0.0, 0.0, 1.0]), "camera.up"),
        "vfov": float(c.get("vfov", 40.0)),
    }

    out["suns"] = []
    finite_sun = False
    for i, l in enumerate(scene.get("light", [])):
        t = l.get("type")
        if t != "sun":
            raise Unsupported(f"[[light]] #{i + 1}: key 'type' = {t!r} is not supported (only \"sun\")")
        check_keys(l, {"type", "direction", "irradiance", "angle"}, f"[[light]] #{i + 1} (sun)")
        angle = float(l.get("angle", 0.0))
        if angle != 0.0:
            if not delta_sun:
                raise Unsupported(
                    f"[[light]] #{i + 1}: key 'angle' = {angle} (a finite sun) is not supported: "
                    "Mitsuba has no uniform sun disc. Pass --delta-sun to render BOTH images "
                    "with angle = 0 instead")
            finite_sun = True
        out["suns"].append({
            "direction": normalize(vec3(l["direction"], "light.direction")),
            "irradiance": rgb(l["irradiance"], "light.irradiance"),
        })
    out["finite_sun"] = finite_sun

    e = scene.get("environment", {})
    check_keys(e, {"radiance"}, "[environment]")
    out["env"] = rgb(e.get("radiance", 0.0), "environment.radiance")

    vols = scene.get("volume", [])
    if len(vols) != 1:
        raise Unsupported(f"[[volume]]: this script supports exactly one volume, found {len(vols)}")
    v = vols[0]
    check_keys(v, {"file", "density_grid", "transform", "material"}, "[[volume]]")
    tr = v.get("transform", {})
    check_keys(tr, {"translate"}, "[volume.transform]")
    ss, sa, phase = material_coefficients(v.get("material", {}))
    out["volume"] = {
        "file": (base / v["file"]).resolve(),
        "grid": v.get("density_grid", "density"),
        "translate": vec3(tr.get("translate", [0.0, 0.0, 0.0]), "transform.translate"),
        "sigma_s": ss, "sigma_a": sa, "phase": phase,
    }
    return scene, out


def delta_sun_copy(scene, toml_path, json_path):
    """The scene as JSON (vdbphoton reads it by extension) with every sun's
    angle set to 0 and the volume path made absolute."""
    s = copy.deepcopy(scene)
    for l in s.get("light", []):
        if l.get("type") == "sun":
            l["angle"] = 0.0
    for v in s.get("volume", []):
        v["file"] = str((toml_path.parent / v["file"]).resolve())
    s.get("render", {}).pop("output", None)
    s.get("render", {}).pop("preview", None)
    json_path.write_text(json.dumps(s, indent=2))


# ---------------------------------------------------------------- Mitsuba

def read_vol_header(path):
    with open(path, "rb") as f:
        h = f.read(48)
    if h[:3] != b"VOL" or h[3] != 3:
        raise RuntimeError(f"{path}: not a VOL v3 file")
    enc, nx, ny, nz, ch = struct.unpack("<5i", h[4:24])
    box = struct.unpack("<6f", h[24:48])
    if enc != 1 or ch != 1:
        raise RuntimeError(f"{path}: expected float32 with 1 channel, got encoding {enc}, {ch} channels")
    return (nx, ny, nz), list(box[:3]), list(box[3:])


def import_mitsuba():
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        cands = sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM.so.19*")
                       + glob.glob("/usr/lib/llvm-19/lib/libLLVM*.so*"))
        if cands:
            os.environ["DRJIT_LIBLLVM_PATH"] = cands[0]
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        sys.exit(f"error: cannot import Mitsuba ({e}); see the set-up in this script's docstring")
    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception as e:
        sys.exit(f"error: Mitsuba variant llvm_ad_rgb unavailable ({e}); install libllvm19 "
                 "and set DRJIT_LIBLLVM_PATH to its libLLVM.so (dpkg -L libllvm19)")
    ver = dr.detail.llvm_version()
    if ver[0] < 16:
        sys.exit(f"error: Dr.Jit loaded libLLVM {'.'.join(map(str, ver))}; Mitsuba's first kernel "
                 "aborts with LLVM 14/15. Install libllvm19 and set DRJIT_LIBLLVM_PATH")
    return dr, mi, ver


def mitsuba_scene_dict(mi, sc, vol_path, spp_pass):
    (nx, ny, nz), wlo, whi = read_vol_header(vol_path)
    t = sc["volume"]["translate"]
    wlo = [a + b for a, b in zip(wlo, t)]
    whi = [a + b for a, b in zip(whi, t)]
    bmin = [min(a, b) for a, b in zip(wlo, whi)]
    bmax = [max(a, b) for a, b in zip(wlo, whi)]
    cam = sc["camera"]
    if all(lo < p < hi for p, lo, hi in zip(cam["position"], bmin, bmax)):
        raise Unsupported("[camera] position: the camera is inside the volume's box "
                          "(the Mitsuba scene puts the medium only inside the box)")

    ss, sa = sc["volume"]["sigma_s"], sc["volume"]["sigma_a"]
    st = [a + b for a, b in zip(ss, sa)]
    if max(st) - min(st) > 1e-6 * max(max(st), 1e-30):
        raise Unsupported(
            f"[volume.material]: extinction differs per channel (sigma_t = {st}); Mitsuba's "
            "heterogeneous medium takes sigma_t = one grid times a single scalar `scale`")
    scale = st[0]
    albedo = [s / t_ if t_ > 0 else 0.0 for s, t_ in zip(ss, st)]
    phase = sc["volume"]["phase"]

    d = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": sc["max_bounces"] + 1,
                       "rr_depth": sc["max_bounces"] + 1},
        "sensor": {
            "type": "perspective",
            "fov": cam["vfov"], "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=cam["position"], target=cam["look_at"], up=cam["up"]),
            "sampler": {"type": "independent", "sample_count": spp_pass},
            "film": {"type": "hdrfilm", "width": sc["width"], "height": sc["height"],
                     "pixel_format": "rgb", "component_format": "float32",
                     "sample_border": False, "rfilter": {"type": "box"}},
        },
        "environment": {"type": "constant", "radiance": {"type": "rgb", "value": sc["env"]}},
    }
    for i, s in enumerate(sc["suns"]):
        d[f"sun{i}"] = {"type": "directional",
                        "direction": [-x for x in s["direction"]],
                        "irradiance": {"type": "rgb", "value": s["irradiance"]}}
    if scale > 0:
        medium = {
            "type": "heterogeneous",
            "sigma_t": {"type": "gridvolume", "filename": str(vol_path),
                        "filter_type": "trilinear", "wrap_mode": "clamp",
                        "to_world": mi.ScalarTransform4f().translate(wlo).scale(
                            [b - a for a, b in zip(wlo, whi)])},
            "scale": scale,
            "albedo": (albedo[0] if albedo[0] == albedo[1] == albedo[2]
                       else {"type": "rgb", "value": albedo}),
            "phase": ({"type": "hg", "g": phase[1]} if phase[0] == "hg"
                      else {"type": "isotropic"}),
        }
        center = [(a + b) / 2 for a, b in zip(bmin, bmax)]
        half = [(b - a) / 2 for a, b in zip(bmin, bmax)]
        d["boundary"] = {"type": "cube",
                         "to_world": mi.ScalarTransform4f().translate(center).scale(half),
                         "bsdf": {"type": "null"}, "interior": medium}
    info = (f"grid {nx}x{ny}x{nz}, box {fmt(bmin)} .. {fmt(bmax)}, sigma_t scale {scale:g}, "
            f"albedo {fmt(albedo)}, phase {phase}")
    return d, info


def fmt(v):
    return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"


def render_mitsuba(dr, mi, sc, vol_path, spp, seed, max_lanes, out_exr):
    pixels = sc["width"] * sc["height"]
    n_pass = max(1, math.ceil(spp * pixels / max_lanes))
    per = [spp // n_pass + (1 if i < spp % n_pass else 0) for i in range(n_pass)]
    d, info = mitsuba_scene_dict(mi, sc, vol_path, per[0])
    print(f"mitsuba scene: {info}")
    t0 = time.perf_counter()
    scene = mi.load_dict(d)
    t_load = time.perf_counter() - t0
    acc = None
    t0 = time.perf_counter()
    for i, p in enumerate(per):
        img = mi.render(scene, spp=p, seed=seed + i) * p
        acc = img if acc is None else acc + img
        dr.eval(acc)
    acc = acc / spp
    dr.eval(acc)
    dr.sync_thread()  # the LLVM backend runs kernels asynchronously
    t_render = time.perf_counter() - t0
    mi.Bitmap(acc, pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(out_exr))
    mean = float(dr.mean(acc.array)[0])
    print(f"mitsuba: {spp} spp in {n_pass} pass(es) {per}, render {t_render:.2f} s "
          f"(scene load {t_load:.2f} s), image mean {mean:.6f} -> {out_exr}")


# ---------------------------------------------------------------- main

def run(cmd):
    print("$ " + " ".join(str(c) for c in cmd), flush=True)
    res = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if res.returncode != 0:
        sys.stderr.write(res.stdout + res.stderr)
        sys.exit(f"error: {cmd[0]} {cmd[1]} failed (exit {res.returncode})")
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", type=Path)
    ap.add_argument("--spp-mitsuba", type=int, default=256)
    ap.add_argument("--spp-vdbphoton", type=int, default=256)
    ap.add_argument("--out", type=Path, default=REPO / "out" / "mitsuba_compare")
    ap.add_argument("--seed-mitsuba", type=int, default=1,
                    help="seed of Mitsuba's first pass (pass i uses seed + i)")
    ap.add_argument("--max-lanes", type=int, default=1 << 22,
                    help="samples per Mitsuba pass (memory bound); default 4194304")
    ap.add_argument("--delta-sun", action="store_true",
                    help="render finite suns (angle > 0) as delta lights in BOTH renderers")
    ap.add_argument("--vdbphoton", type=Path,
                    default=Path(os.environ.get("VDBPHOTON", REPO / "target/release/vdbphoton")))
    a = ap.parse_args()
    if a.spp_mitsuba < 1 or a.spp_vdbphoton < 1:
        sys.exit("error: spp must be >= 1")
    if not a.vdbphoton.is_file():
        sys.exit(f"error: {a.vdbphoton} not found (cargo build --release, or pass --vdbphoton)")
    toml_path = a.scene.resolve()
    try:
        scene, sc = parse_scene(toml_path, a.delta_sun)
    except Unsupported as e:
        sys.exit(f"{a.scene}: unsupported: {e}")
    except (tomllib.TOMLDecodeError, OSError, KeyError, ValueError, TypeError) as e:
        sys.exit(f"{a.scene}: cannot read scene: {e!r}")
    a.out.mkdir(parents=True, exist_ok=True)
    out = a.out.resolve()

    vol = out / "density.vol"
    run([a.vdbphoton, "export-vol", sc["volume"]["file"], vol, "--grid", sc["volume"]["grid"]])

    dr, mi, llvm = import_mitsuba()
    print(f"Mitsuba {mi.__version__}, variant {mi.variant()}, libLLVM {'.'.join(map(str, llvm))}")
    try:
        render_mitsuba(dr, mi, sc, vol, a.spp_mitsuba, a.seed_mitsuba, a.max_lanes,
                       out / "mitsuba.exr")
    except Unsupported as e:
        sys.exit(f"{a.scene}: unsupported: {e}")

    vdb_scene = toml_path
    if sc["finite_sun"]:
        vdb_scene = out / "scene.json"
        delta_sun_copy(scene, toml_path, vdb_scene)
        print(f"--delta-sun: suns rendered with angle 0 by both renderers ({vdb_scene})")
    t0 = time.perf_counter()
    run([a.vdbphoton, "render", vdb_scene, "-o", out / "vdbphoton.exr",
         "--preview", out / "vdbphoton.png", "--spp", a.spp_vdbphoton, "-q"])
    print(f"vdbphoton: {a.spp_vdbphoton} spp, wall {time.perf_counter() - t0:.2f} s "
          f"-> {out / 'vdbphoton.exr'}")

    res = run([a.vdbphoton, "compare", out / "vdbphoton.exr", out / "mitsuba.exr"])
    print("vdbphoton vs Mitsuba (reference):")
    sys.stdout.write(res.stdout + res.stderr)
    means = {}
    for name in ("vdbphoton", "mitsuba"):
        t = mi.TensorXf(mi.Bitmap(str(out / f"{name}.exr")))
        means[name] = [float(dr.mean(t[..., c].array)[0]) for c in range(3)]
    print("per-channel means R, G, B: vdbphoton " + fmt(means["vdbphoton"]) + ", mitsuba "
          + fmt(means["mitsuba"]) + ", ratio "
          + fmt([a / b if b else float("nan") for a, b in zip(means["vdbphoton"], means["mitsuba"])]))


if __name__ == "__main__":
    main()
