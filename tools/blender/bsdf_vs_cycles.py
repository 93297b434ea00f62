"""Render flat planes of Blender's Principled BSDF and Diffuse BSDF under a
sun with Blender 5.0.1 Cycles (the `bpy` module) and write the radiance each
reflects and Cycles' Denoising Albedo pass, for `tests/bsdf.rs`
(`surfaces_match_cycles_renders`) to compare with f(wo, wi) cos(theta_i) E
and the albedo guide from `vdbphoton::bsdf`.

Usage:
    VENV/bin/python tools/blender/bsdf_vs_cycles.py OUT.json

VENV is a Python 3.11 venv with `pip install bpy==5.0.1`.

Each case is one render of one plane: a 100 x 100 plane through the origin
with normal +Z (flat shaded), an orthographic camera looking along -wo at it
(4 x 4 pixels, all on the plane), a sun of strength E (irradiance on a
surface facing it, W/m^2) and angle 0 whose light travels along -wi, a black
world, and nothing else. With Total Bounces 0 Cycles lights the plane
directly only, and a delta light is found by next-event estimation alone,
so every sample of every pixel is the same number: the plane's radiance
towards the camera, L = f(wo, wi) cos(theta_i) E exactly, with f as Cycles
evaluates it. Nothing that would bias it is on: no clamping, no adaptive
sampling, no denoising, Standard view transform; the EXR is linear float32.
wo and wi are in the plane's frame (z = normal), which here is the world's.
The Denoising Albedo pass (View Layer > Denoising Data) is as deterministic:
the diffuse-like closures' albedo estimates seen from wo, or, when 75 % of
the sample weight is in sharp closures, what the reflected ray finds (here
nothing: with Total Bounces 0 it is not traced, so 0).
"""

import json
import math
import os
import sys
import tempfile

import bpy
from mathutils import Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from denoise_vs_cycles import read_exr  # noqa: E402 (a plain-Python EXR reader)

E = 3.0


def direction(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def cases():
    """(name, shader, inputs, wo, wi); wo in the xz-plane (phi 0)."""
    principled = "principled"
    diffuse = "diffuse"
    out = []

    def add(name, shader, inputs, wo_theta, wi_theta, wi_phi):
        out.append((name, shader, inputs, direction(wo_theta, 0.0), direction(wi_theta, wi_phi)))

    base = {"Base Color": [0.8, 0.5, 0.2]}
    add("diffuse lambert", diffuse, {"Color": [0.8, 0.5, 0.2], "Roughness": 0.0}, 30, 50, 180)
    add("diffuse oren-nayar 0.5 back", diffuse, {"Color": [0.8, 0.5, 0.2], "Roughness": 0.5}, 40, 60, 20)
    add("diffuse oren-nayar 1 forward", diffuse, {"Color": [0.9, 0.9, 0.9], "Roughness": 1.0}, 60, 45, 170)
    add("principled default straight on", principled, {}, 0, 40, 180)
    add("principled default near mirror", principled, dict(base), 45, 40, 180)
    add("principled default off mirror", principled, dict(base), 30, 60, 90)
    add("principled default grazing view", principled, dict(base), 80, 30, 180)
    add("principled default grazing light", principled, dict(base), 20, 85, 170)
    add("principled r0.05 mirror", principled, dict(base, Roughness=0.05), 50, 50, 180)
    add("principled r0.05 off mirror", principled, dict(base, Roughness=0.05), 50, 45, 175)
    add("principled r0.2", principled, dict(base, Roughness=0.2), 35, 30, 170)
    add("principled r1", principled, dict(base, Roughness=1.0), 60, 50, 150)
    add("principled r1 ggx", principled, dict(base, Roughness=1.0, distribution="GGX"), 60, 50, 150)
    add("principled r0 (mirror: diffuse only)", principled, dict(base, Roughness=0.0), 30, 40, 180)
    add("principled level 0", principled, dict(base, **{"Specular IOR Level": 0.0}), 40, 40, 180)
    add("principled level 1 tint", principled,
        dict(base, **{"Specular IOR Level": 1.0, "Specular Tint": [1.0, 0.6, 0.3]}), 40, 45, 180)
    add("principled ior 1.33", principled, dict(base, IOR=1.33, Roughness=0.3), 55, 50, 180)
    add("principled ior 2.5", principled, dict(base, IOR=2.5, Roughness=0.3), 55, 50, 180)
    add("principled diffuse roughness 0.7", principled,
        dict(base, **{"Diffuse Roughness": 0.7, "Roughness": 0.6}), 50, 60, 30)
    copper = [0.955, 0.638, 0.538]
    add("metal copper r0.3", principled, {"Base Color": copper, "Metallic": 1.0, "Roughness": 0.3}, 40, 45, 180)
    add("metal copper r0.3 tint grazing", principled,
        {"Base Color": copper, "Metallic": 1.0, "Roughness": 0.3, "Specular Tint": [1.0, 0.7, 0.5]}, 75, 75, 180)
    add("metal gold r0.7", principled, {"Base Color": [1.0, 0.78, 0.34], "Metallic": 1.0, "Roughness": 0.7}, 20, 60, 100)
    add("half metal r0.4", principled, dict(base, Metallic=0.5, Roughness=0.4), 45, 35, 160)
    add("white principled r0.5", principled, {"Base Color": [1.0, 1.0, 1.0]}, 30, 30, 180)
    add("metal gold r0.1 (sharp: albedo guide passed on)", principled,
        {"Base Color": [1.0, 0.78, 0.34], "Metallic": 1.0, "Roughness": 0.1}, 30, 32, 180)
    add("half metal r0.2", principled, dict(base, Metallic=0.7, Roughness=0.2), 50, 50, 175)
    return out


def setup_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = 4
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.use_light_tree = False
    c.light_sampling_threshold = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.seed = 1
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.resolution_x = 4
    scene.render.resolution_y = 4
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.view_layers[0].cycles.denoising_store_passes = True
    s = scene.render.image_settings
    s.media_type = "MULTI_LAYER_IMAGE"
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.exr_codec = "ZIP"
    s.color_depth = "32"
    s.color_mode = "RGBA"

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world

    bpy.ops.mesh.primitive_plane_add(size=100.0, location=(0, 0, 0))
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("surface")
    mat.use_nodes = True
    plane.data.materials.append(mat)

    cam_data = bpy.data.cameras.new("cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 0.01
    cam_data.clip_start = 1e-3
    cam_data.clip_end = 100.0
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam

    sun_data = bpy.data.lights.new("sun", "SUN")
    sun_data.energy = E
    sun_data.angle = 0.0
    sun = bpy.data.objects.new("sun", sun_data)
    scene.collection.objects.link(sun)
    return scene, mat, cam, sun


def set_material(mat, shader, inputs):
    nodes = mat.node_tree.nodes
    for n in list(nodes):
        if n.type != "OUTPUT_MATERIAL":
            nodes.remove(n)
    out = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
    if shader == "principled":
        node = nodes.new("ShaderNodeBsdfPrincipled")
        node.distribution = inputs.get("distribution", "MULTI_GGX")
    else:
        node = nodes.new("ShaderNodeBsdfDiffuse")
    for key, value in inputs.items():
        if key == "distribution":
            continue
        sock = node.inputs[key]
        if isinstance(value, list):
            sock.default_value = value + [1.0]
        else:
            sock.default_value = value
    mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])


def mean_rgb(channels, prefix):
    """Mean over the pixels of a pass, and the largest departure from it."""
    rgb = [float(channels[prefix + c].mean()) for c in "RGB"]
    spread = max(float(abs(channels[prefix + c] - rgb[i]).max()) for i, c in enumerate("RGB"))
    return rgb, spread


def main():
    out_path = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
    scene, mat, cam, sun = setup_scene()
    results = []
    tmp = tempfile.mkdtemp(prefix="bsdf_vs_cycles")
    for name, shader, inputs, wo, wi in cases():
        set_material(mat, shader, inputs)
        wo_v, wi_v = Vector(wo), Vector(wi)
        cam.location = wo_v * 10.0
        cam.rotation_mode = "QUATERNION"
        cam.rotation_quaternion = (-wo_v).to_track_quat("-Z", "Y")
        sun.rotation_mode = "QUATERNION"
        sun.rotation_quaternion = wi_v.to_track_quat("Z", "Y")
        path = os.path.join(tmp, "case.exr")
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
        channels, _ = read_exr(path)
        layer = scene.view_layers[0].name
        rgb, spread = mean_rgb(channels, f"{layer}.Combined.")
        albedo, spread_a = mean_rgb(channels, f"{layer}.Denoising Albedo.")
        print(f"{name}: {rgb} albedo {albedo} (pixel spreads {spread:.2e} {spread_a:.2e})", flush=True)
        results.append(
            {
                "name": name,
                "shader": shader,
                "inputs": inputs,
                "wo": wo,
                "wi": wi,
                "sun_strength": E,
                "radiance": rgb,
                "denoising_albedo": albedo,
            }
        )
    doc = {
        "about": "Blender 5.0.1 Cycles: radiance of a flat plane lit by a sun (angle 0) "
        "of strength sun_strength arriving from wi, seen along -wo (plane frame, z = "
        "normal), Total Bounces 0, and its Denoising Albedo pass; "
        "tools/blender/bsdf_vs_cycles.py",
        "blender": bpy.app.version_string,
        "cases": results,
    }
    with open(out_path, "w") as f:
        json.dump(doc, f, indent=1)


main()
