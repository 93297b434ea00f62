"""Make the view-transform test EXR and Blender's reference PNGs.

Run with Blender's Python module (bpy), e.g.
    /work/venv-bpy/bin/python make_view_refs.py [OUT_DIR]

Writes into OUT_DIR (default: the folder of this script):
    view_test.exr         64x64 float32 RGB, ZIP, scene-linear Rec.709
    blender_standard.png  "Save as Render", display sRGB, view Standard
    blender_agx.png       same, view AgX   (look None)
    blender_filmic.png    same, view Filmic (look None)
All PNGs: 8-bit RGB, exposure 0, gamma 1, no curves, no white balance,
dither_intensity 0 (Blender's default is 1.0, which adds noise).

The test image content is generated here from formulas (numpy only,
fixed seed), so the EXR can be re-made bit-for-bit.
"""
import os
import sys

import numpy as np

import bpy

W = H = 64


def blackbody_rgb(temps):
    """Linear Rec.709 colour of a blackbody, luminance normalised to 1.

    CIE 1931 2-degree matching functions from the multi-lobe Gaussian fit of
    Wyman, Sloan & Shirley (JCGT 2013); Planck's law; XYZ->Rec.709 (D65)."""
    lam = np.arange(360.0, 831.0, 1.0)  # nm

    def g(x, mu, s1, s2):
        s = np.where(x < mu, s1, s2)
        return np.exp(-0.5 * ((x - mu) / s) ** 2)

    xb = (1.056 * g(lam, 599.8, 37.9, 31.0) + 0.362 * g(lam, 442.0, 16.0, 26.7)
          - 0.065 * g(lam, 501.1, 20.4, 26.2))
    yb = 0.821 * g(lam, 568.8, 46.9, 40.5) + 0.286 * g(lam, 530.9, 16.3, 31.1)
    zb = 1.217 * g(lam, 437.0, 11.8, 36.0) + 0.681 * g(lam, 459.0, 26.0, 13.8)
    c2 = 1.4388e7  # nm K
    out = []
    for t in temps:
        spd = lam ** -5.0 / np.expm1(c2 / (lam * t))
        xyz = np.array([np.sum(spd * xb), np.sum(spd * yb), np.sum(spd * zb)])
        xyz /= xyz[1]
        m = np.array([[3.2409699, -1.5373832, -0.4986108],
                      [-0.9692436, 1.8759675, 0.0415551],
                      [0.0556301, -0.2039770, 1.0569715]])
        out.append(m @ xyz)
    return np.array(out)


def hsv_colour(h, s):
    """Linear RGB with max component 1 for hue h in [0,1), saturation s."""
    k = (np.array([5.0, 3.0, 1.0]) + h * 6.0) % 6.0
    return 1.0 - s * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)


def make_test_image():
    img = np.zeros((H, W, 3), np.float64)  # row 0 = top of the picture
    lum = np.array([0.2126, 0.7152, 0.0722])
    # rows 0-1: grey ramp, 0.18 * 2^(-10 .. +10), 128 steps
    st = np.linspace(-10.0, 10.0, 2 * W)
    img[0:2] = (0.18 * 2.0 ** st).reshape(2, W)[..., None]
    # rows 2-3: special values (zero, negatives, tiny, huge, mixed sign)
    specials = [
        (0, 0, 0), (1e-9, 1e-9, 1e-9), (1e-4, 1e-4, 1e-4), (-1e-3, -1e-3, -1e-3),
        (-0.05, -0.05, -0.05), (-1, -1, -1), (1, 1, 1), (0.18, 0.18, 0.18),
        (100, 100, 100), (1000, 1000, 1000), (1e4, 1e4, 1e4), (65504, 65504, 65504),
        (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (0, 1, 1), (1, 0, 1),
        (0.5, -0.05, 0.1), (-0.1, 0.2, 0.3), (0.3, 0.2, -0.1), (-0.2, 0.8, -0.05),
        (0.02, -0.01, 0.3), (2.0, -0.2, -0.2), (-0.3, -0.3, 2.0), (-0.5, 1.5, 0.1),
        (5, 0, 0), (0, 5, 0), (0, 0, 5), (20, 0, 0), (0, 20, 0), (0, 0, 20),
        (50, 5, 0.5), (0.5, 5, 50), (5, 50, 0.5), (1e3, 10, 0), (0, 10, 1e3),
    ]
    flat = np.zeros((2 * W, 3))
    flat[:len(specials)] = specials
    # fill the rest with pure primaries/secondaries at rising exposure
    prim = np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (0, 1, 1), (1, 0, 1),
                     (1, 0.5, 0), (0.5, 0, 1)], float)
    rest = 2 * W - len(specials)
    for i in range(rest):
        flat[len(specials) + i] = prim[i % len(prim)] * 2.0 ** (-8 + 18 * (i // len(prim)) / (rest // len(prim)))
    img[2:4] = flat.reshape(2, W, 3)
    # rows 4-27: 16 hues x 4 saturations, 24 exposures (-8 .. +10 stops
    # relative to a luminance of 0.18)
    hs = np.arange(16) / 16.0
    sats = [1.0, 0.8, 0.5, 0.2]
    for r, e in enumerate(np.linspace(-8.0, 10.0, 24)):
        for si, s in enumerate(sats):
            for hi, h in enumerate(hs):
                c = hsv_colour(h, s)
                c = c / (c @ lum) * 0.18 * 2.0 ** e
                img[4 + r, si * 16 + hi] = c
    # rows 28-43: blackbody 800 K .. 12000 K (64 temps) x 16 exposures
    temps = np.geomspace(800.0, 12000.0, W)
    bb = blackbody_rgb(temps)
    for r, e in enumerate(np.linspace(-6.0, 12.0, 16)):
        img[28 + r] = bb * 0.18 * 2.0 ** e
    # rows 44-51: out-of-Rec.709 colours (Rec.2020 / wide primaries) and
    # smoke-like tinted greys
    m2020_to_709 = np.array([[1.6604910, -0.5876411, -0.0728499],
                             [-0.1245505, 1.1328999, -0.0083494],
                             [-0.0181508, -0.1005789, 1.1187297]])
    for r, e in enumerate(np.linspace(-6.0, 8.0, 4)):
        for i in range(W):
            c2020 = hsv_colour(i / W, 1.0 if i % 2 == 0 else 0.85)
            c = m2020_to_709 @ c2020
            img[44 + r, i] = c / max(c @ lum, 1e-3) * 0.18 * 2.0 ** e
    tints = np.array([(1.0, 0.95, 0.9), (0.9, 0.95, 1.0), (1.0, 1.0, 1.0), (0.95, 0.9, 0.8)])
    for r in range(4):
        e = np.linspace(-9.0, 4.0, W)
        img[48 + r] = tints[r][None, :] * (0.18 * 2.0 ** e)[:, None]
    # rows 52-63: random "rendered" colours: log-uniform intensity,
    # random chroma, mostly positive, a few small negatives
    rng = np.random.default_rng(20260518)
    n = 12 * W
    inten = 0.18 * 2.0 ** rng.uniform(-10.0, 10.0, n)
    chroma = rng.dirichlet([0.6, 0.6, 0.6], n) * 3.0
    mix = rng.uniform(0.0, 1.0, n)[:, None]
    c = inten[:, None] * (mix * chroma + (1 - mix))
    c[rng.uniform(0, 1, n) < 0.05] *= np.array([1.0, -0.02, 1.0])
    img[52:64] = c.reshape(12, W, 3)
    return img.astype(np.float32)


def import_bundled_oiio():
    base = bpy.utils.resource_path("LOCAL")  # .../site-packages/bpy/5.0
    sys.path.append(os.path.join(base, "python", "lib",
                                 "python%d.%d" % sys.version_info[:2], "site-packages"))
    import OpenImageIO
    return OpenImageIO


def main():
    out_dir = sys.argv[-1] if len(sys.argv) > 1 and os.path.isdir(sys.argv[-1]) \
        else os.path.dirname(os.path.abspath(__file__))
    exr_path = os.path.join(out_dir, "view_test.exr")
    scene = bpy.context.scene

    # --- 1. write the EXR with the OpenImageIO bundled in the bpy package ---
    # (bpy's Image.save() of a generated float image is not a plain linear
    # write in 5.0.1: it pushes the pixels through colour management, so it
    # is not used here.)
    arr = make_test_image()
    oiio = import_bundled_oiio()
    spec = oiio.ImageSpec(W, H, 3, oiio.FLOAT)
    spec.attribute("compression", "zip")
    spec.attribute("oiio:ColorSpace", "lin_rec709")
    # fixed date, else OIIO stamps the current time and Blender copies it
    # into the PNGs' metadata: keeps every file byte-for-byte reproducible
    spec.attribute("DateTime", "2025:01:01 00:00:00")
    out = oiio.ImageOutput.create(exr_path)
    assert out.open(exr_path, spec), oiio.geterror()
    assert out.write_image(np.ascontiguousarray(arr)), out.geterror()
    out.close()

    # --- 2. load it back as Blender would, and "Save as Render" to PNG ---
    src = bpy.data.images.load(exr_path)
    # Blender's default for float EXR files is the role default_float, i.e.
    # "Linear Rec.709" (= scene linear), so no input conversion happens.
    assert src.colorspace_settings.name == "Linear Rec.709", src.colorspace_settings.name
    got = np.empty(W * H * 4, np.float32)
    src.pixels.foreach_get(got)
    got = got.reshape(H, W, 4)[::-1, :, :3]
    assert np.array_equal(got, arr), "EXR round trip changed the pixels"

    scene.display_settings.display_device = "sRGB"
    vs = scene.view_settings
    vs.exposure = 0.0
    vs.gamma = 1.0
    vs.use_curve_mapping = False
    vs.use_white_balance = False
    scene.render.dither_intensity = 0.0
    s = scene.render.image_settings
    s.file_format = "PNG"
    s.color_mode = "RGB"
    s.color_depth = "8"
    s.compression = 100
    s.color_management = "FOLLOW_SCENE"
    for view, name in (("Standard", "standard"), ("AgX", "agx"), ("Filmic", "filmic")):
        vs.view_transform = view
        vs.look = "None"
        path = os.path.join(out_dir, "blender_%s.png" % name)
        src.save_render(path, scene=scene)
        print("wrote", path)
    print("Blender", bpy.app.version_string, "OCIO", bpy.app.ocio.version_string.strip())


if __name__ == "__main__":
    main()
