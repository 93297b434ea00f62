use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat3, DVec3, Vec3};
use vdbphoton::scene::{
    CameraDesc, CameraPose, EnvironmentDesc, Lens, LightDesc, MaterialDesc, MotionBlurDesc,
    PathSeg, PhaseDesc, Principled, RenderDesc, SceneDesc, SceneError, SceneFormat,
    ShutterPosition,
};

const VOL: &str = "[[volume]]\nfile = \"a.vdb\"\n";

/// Scenes are loaded as the renderer loads them: with the integrators'
/// check of their settings tables (`vdbphoton::render::load_scene`).
fn toml(text: &str) -> Result<SceneDesc, SceneError> {
    SceneDesc::from_str_checked(
        text,
        SceneFormat::Toml,
        "/s",
        "scene.toml",
        &vdbphoton::integrator::check_settings,
    )
}

fn json(text: &str) -> Result<SceneDesc, SceneError> {
    SceneDesc::from_str_checked(
        text,
        SceneFormat::Json,
        "/s",
        "scene.json",
        &vdbphoton::integrator::check_settings,
    )
}

fn ok(text: &str) -> SceneDesc {
    toml(text).unwrap_or_else(|e| panic!("{e}"))
}

/// The error message, checked to be one line starting with the file name.
fn err(result: Result<SceneDesc, SceneError>) -> String {
    let msg = result.expect_err("expected an error").to_string();
    assert!(!msg.contains('\n'), "multi-line message: {msg:?}");
    assert!(msg.starts_with("scene."), "no file name: {msg}");
    msg
}

fn toml_err(text: &str) -> String {
    err(toml(text))
}

fn volume0(scene: &SceneDesc) -> &vdbphoton::scene::VolumeDesc {
    &scene.volumes[0]
}

// ---------------------------------------------------------------- parsing

#[test]
fn reference_scene() {
    let path = Path::new("/work/shared/data/reference/cloud96_sun.toml");
    let scene = SceneDesc::load(path).unwrap();
    let r = &scene.render;
    assert_eq!(
        (r.width, r.height, r.spp, r.seed, r.max_bounces),
        (256, 192, 64, 0, 256)
    );
    assert_eq!(r.integrator, "auto");
    assert_eq!(r.output, Path::new("/work/shared/data/reference/out.exr"));
    assert_eq!((r.preview.clone(), r.exposure, r.aovs), (None, 0.0, false));
    assert_eq!(
        scene.camera,
        CameraDesc {
            pose: CameraPose::LookAt {
                position: Vec3::new(3.2, -2.8, 1.4),
                look_at: Vec3::ZERO,
                up: Vec3::Z,
            },
            lens: Lens::Vfov(38.0),
            shift: [0.0, 0.0],
        }
    );
    assert_eq!(
        scene.lights,
        vec![LightDesc::Sun {
            direction: Vec3::new(-0.4, -0.5, 0.75),
            irradiance: Vec3::splat(2.0),
            angle_deg: 0.0,
        }]
    );
    assert_eq!(
        scene.environment,
        EnvironmentDesc::Constant(Vec3::splat(0.1))
    );
    assert_eq!(scene.volumes.len(), 1);
    let v = volume0(&scene);
    assert_eq!(v.file, PathBuf::from("/work/shared/data/cloud96.vdb"));
    assert!(v.file.exists());
    assert_eq!(v.density_grid, "density");
    assert_eq!(
        (&v.temperature_grid, &v.flame_grid, &v.color_grid),
        (&None, &None, &None)
    );
    assert_eq!(v.transform, DAffine3::IDENTITY);
    assert_eq!(
        v.material,
        MaterialDesc::Raw {
            sigma_a: Vec3::splat(2.0),
            sigma_s: Vec3::splat(20.0),
            emission: Vec3::ZERO,
            phase: PhaseDesc::Hg { g: 0.3 },
        }
    );
}

#[test]
fn defaults_when_keys_are_absent() {
    let scene = ok(VOL);
    assert_eq!(
        scene.render,
        RenderDesc {
            width: 320,
            height: 240,
            spp: 64,
            seed: 0,
            max_bounces: 256,
            integrator: "auto".into(),
            settings: Default::default(),
            output: PathBuf::from("/s/out.exr"),
            preview: None,
            exposure: 0.0,
            aovs: false,
            frames: None,
            motion_blur: MotionBlurDesc {
                enabled: false,
                shutter: 0.5,
                position: ShutterPosition::Center,
                fps: 24.0,
            },
            denoise: false,
            denoise_quality: vdbphoton::scene::DenoiseQuality::High,
            resume: false,
            film_transparent: false,
        }
    );
    assert!(scene.meshes.is_empty());
    assert_eq!(
        scene.camera.pose,
        CameraPose::LookAt {
            position: Vec3::new(0.0, -4.5, 0.6),
            look_at: Vec3::ZERO,
            up: Vec3::Z
        }
    );
    assert_eq!(scene.camera.lens, Lens::Vfov(40.0));
    assert!(scene.lights.is_empty());
    assert_eq!(scene.environment, EnvironmentDesc::Constant(Vec3::ZERO));
    let v = volume0(&scene);
    assert_eq!(v.file, PathBuf::from("/s/a.vdb"));
    assert_eq!(v.density_grid, "density");
    assert_eq!(v.temperature_grid, None);
    assert_eq!(v.transform, DAffine3::IDENTITY);
    assert_eq!(
        v.material,
        MaterialDesc::Principled(Principled {
            density: 1.0,
            color: Vec3::splat(0.5),
            absorption_color: Vec3::ZERO,
            anisotropy: 0.0,
            emission_strength: 0.0,
            emission_color: Vec3::ONE,
            blackbody_intensity: 0.0,
            blackbody_tint: Vec3::ONE,
            temperature: 1000.0,
        })
    );
    // Light defaults: sun angle 0; spot cone 45°, blend 0.15 (Blender's).
    let scene = ok(&format!(
        "[[light]]\ntype = \"sun\"\ndirection = [0, 0, 1]\nirradiance = 1\n\
         [[light]]\ntype = \"spot\"\nposition = [0, 0, 5]\ndirection = [0, 0, -1]\nintensity = 10\n{VOL}"
    ));
    assert_eq!(
        scene.lights,
        vec![
            LightDesc::Sun {
                direction: Vec3::Z,
                irradiance: Vec3::ONE,
                angle_deg: 0.0
            },
            LightDesc::Spot {
                position: Vec3::new(0.0, 0.0, 5.0),
                direction: -Vec3::Z,
                intensity: Vec3::splat(10.0),
                cone_angle_deg: 45.0,
                blend: 0.15,
            },
        ]
    );
}

#[test]
fn render_keys_and_paths() {
    let scene = ok(&format!(
        "[render]\nwidth = 64\nheight = 32\nspp = 4\nseed = 7\nmax_bounces = 0\nintegrator = \"path\"\n\
         output = \"renders/./x/../a.exr\"\npreview = \"/abs/p.png\"\nexposure = -1.5\naovs = true\n{VOL}"
    ));
    let r = &scene.render;
    assert_eq!(
        (r.width, r.height, r.spp, r.seed, r.max_bounces),
        (64, 32, 4, 7, 0)
    );
    assert_eq!(r.output, PathBuf::from("/s/renders/a.exr"));
    assert_eq!(r.preview, Some(PathBuf::from("/abs/p.png")));
    assert_eq!((r.exposure, r.aovs), (-1.5, true));
}

#[test]
fn principled_material_with_all_keys() {
    let scene = ok(&format!(
        "{VOL}temperature_grid = \"temperature\"\nflame_grid = \"flame\"\ncolor_grid = \"Cd\"\n\
         [volume.material]\ndensity = 2.5\ncolor = [0.8, 0.7, 0.6]\nabsorption_color = 0.25\n\
         anisotropy = -0.3\nemission_strength = 4\nemission_color = [1.0, 0.5, 0.0]\n\
         blackbody_intensity = 0.75\nblackbody_tint = [1.0, 0.9, 0.8]\ntemperature = 1500\n"
    ));
    let v = volume0(&scene);
    assert_eq!(v.temperature_grid.as_deref(), Some("temperature"));
    assert_eq!(v.flame_grid.as_deref(), Some("flame"));
    assert_eq!(v.color_grid.as_deref(), Some("Cd"));
    assert_eq!(
        v.material,
        MaterialDesc::Principled(Principled {
            density: 2.5,
            color: Vec3::new(0.8, 0.7, 0.6),
            absorption_color: Vec3::splat(0.25),
            anisotropy: -0.3,
            emission_strength: 4.0,
            emission_color: Vec3::new(1.0, 0.5, 0.0),
            blackbody_intensity: 0.75,
            blackbody_tint: Vec3::new(1.0, 0.9, 0.8),
            temperature: 1500.0,
        })
    );
}

fn raw_phase(phase_toml: &str) -> MaterialDesc {
    let scene = ok(&format!(
        "{VOL}[volume.material]\nsigma_s = 3\n{phase_toml}"
    ));
    volume0(&scene).material.clone()
}

#[test]
fn raw_material_and_each_phase_type() {
    assert_eq!(
        ok(&format!(
            "{VOL}[volume.material]\nsigma_s = [30, 20, 10]\nsigma_a = 1.5\nemission = [0.1, 0.2, 0.3]\n"
        ))
        .volumes[0]
            .material,
        MaterialDesc::Raw {
            sigma_a: Vec3::splat(1.5),
            sigma_s: Vec3::new(30.0, 20.0, 10.0),
            emission: Vec3::new(0.1, 0.2, 0.3),
            phase: PhaseDesc::Isotropic,
        }
    );
    let phase = |m: MaterialDesc| match m {
        MaterialDesc::Raw {
            sigma_a,
            sigma_s,
            emission,
            phase,
        } => {
            assert_eq!(
                (sigma_a, sigma_s, emission),
                (Vec3::ZERO, Vec3::splat(3.0), Vec3::ZERO)
            );
            phase
        }
        other => panic!("not raw: {other:?}"),
    };
    assert_eq!(
        phase(raw_phase("phase = { type = \"isotropic\" }")),
        PhaseDesc::Isotropic
    );
    assert_eq!(
        phase(raw_phase("phase = { type = \"hg\", g = 0.6 }")),
        PhaseDesc::Hg { g: 0.6 }
    );
    assert_eq!(
        phase(raw_phase("phase = { type = \"schlick\", g = -0.25 }")),
        PhaseDesc::Schlick { g: -0.25 }
    );
    assert_eq!(
        phase(raw_phase(
            "phase = { type = \"hg_mix\", lobes = [{ g = 0.8, weight = 0.7 }, { g = -0.3, weight = 0.3 }] }"
        )),
        PhaseDesc::HgMix(vec![(0.8, 0.7), (-0.3, 0.3)])
    );
    // Also as a sub-table.
    assert_eq!(
        phase(raw_phase(
            "[volume.material.phase]\ntype = \"hg\"\ng = 0.5\n"
        )),
        PhaseDesc::Hg { g: 0.5 }
    );
    // Cycles 5's Volume Scatter phases.
    assert_eq!(
        phase(raw_phase(
            "phase = { type = \"fournier_forand\", backscatter = 0.1, ior = 1.33 }"
        )),
        PhaseDesc::FournierForand {
            backscatter: 0.1,
            ior: 1.33
        }
    );
    assert_eq!(
        phase(raw_phase(
            "phase = { type = \"draine\", g = 0.4, alpha = 0.5 }"
        )),
        PhaseDesc::Draine { g: 0.4, alpha: 0.5 }
    );
    assert_eq!(
        phase(raw_phase("phase = { type = \"rayleigh\" }")),
        PhaseDesc::Rayleigh
    );
    assert_eq!(
        phase(raw_phase("phase = { type = \"mie\", diameter = 20 }")),
        PhaseDesc::Mie { diameter: 20.0 }
    );
}

/// Cycles 5's phase types: each key required where used, refused where
/// not, and within the range of Blender's Volume Scatter socket.
#[test]
fn error_cycles_phase_keys_and_ranges() {
    let e = |phase: &str| {
        toml_err(&format!(
            "{VOL}[volume.material]\nsigma_s = 1\nphase = {{ {phase} }}\n"
        ))
    };
    let at = "scene.toml:5: key 'phase";
    for (phase, want) in [
        (
            "type = \"fournier_forand\", backscatter = 0.1",
            ".ior' in [volume.material]: missing (required for phase type \"fournier_forand\")",
        ),
        (
            "type = \"fournier_forand\", backscatter = 0.6, ior = 1.33",
            ".backscatter' in [volume.material]: must be in [0, 0.5], got 0.6",
        ),
        (
            "type = \"fournier_forand\", backscatter = 0.1, ior = 0.9",
            ".ior' in [volume.material]: must be in [1, 2], got 0.9",
        ),
        (
            "type = \"draine\", g = 0.5",
            ".alpha' in [volume.material]: missing (required for phase type \"draine\")",
        ),
        (
            "type = \"draine\", g = 0.5, alpha = -1",
            ".alpha' in [volume.material]: must be in [0, 500], got -1",
        ),
        (
            "type = \"draine\", g = -1.5, alpha = 1",
            ".g' in [volume.material]: must be in [-1, 1], got -1.5",
        ),
        (
            "type = \"mie\", diameter = 60",
            ".diameter' in [volume.material]: must be in [0, 50], got 60",
        ),
        (
            "type = \"mie\"",
            ".diameter' in [volume.material]: missing (required for phase type \"mie\")",
        ),
        (
            "type = \"rayleigh\", g = 0.3",
            ".g' in [volume.material]: not used by phase type \"rayleigh\"",
        ),
        (
            "type = \"hg\", g = 0.3, diameter = 20",
            ".diameter' in [volume.material]: not used by phase type \"hg\"",
        ),
        (
            "type = \"mie\", diameter = 20, alpha = 2",
            ".alpha' in [volume.material]: not used by phase type \"mie\"",
        ),
    ] {
        assert_eq!(e(phase), format!("{at}{want}"), "{phase}");
    }
}

const FULL_TOML: &str = r#"
[render]
width = 100
height = 50
spp = 8
seed = 3
integrator = "path"
output = "out/a.exr"
preview = "out/a.png"
exposure = 1.0
aovs = true

[camera]
position = [1, 2, 3]
look_at = [0, 0, 1]
up = [0, 0, 1]
vfov = 30

[[light]]
type = "sun"
direction = [0.5, -0.3, 0.8]
irradiance = 3
angle = 0.5

[[light]]
type = "point"
position = [0, 0, 4]
intensity = [10, 20, 30]

[[light]]
type = "spot"
position = [0, -3, 3]
direction = [0, 1, -1]
intensity = 100
cone_angle = 30
cone_falloff = 0.2

[environment]
map = "sky.exr"
strength = 0.5
rotate_z = 90

[[volume]]
file = "smoke.vdb"
density_grid = "dens"
temperature_grid = "temperature"
transform = { translate = [1, 2, 3], rotate = [0, 0, 90], scale = 2 }
[volume.material]
density = 3
anisotropy = 0.2

[[volume]]
file = "/data/fire.vdb"
transform = { matrix = [[2, 0, 0, 1], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]] }
[volume.material]
sigma_s = 1
phase = { type = "hg_mix", lobes = [{ g = 0.8, weight = 0.7 }, { g = -0.2, weight = 0.3 }] }
"#;

const FULL_JSON: &str = r#"{
  "render": { "width": 100, "height": 50, "spp": 8, "seed": 3, "integrator": "path",
              "output": "out/a.exr", "preview": "out/a.png", "exposure": 1.0, "aovs": true },
  "camera": { "position": [1, 2, 3], "look_at": [0, 0, 1], "up": [0, 0, 1], "vfov": 30 },
  "light": [
    { "type": "sun", "direction": [0.5, -0.3, 0.8], "irradiance": 3, "angle": 0.5 },
    { "type": "point", "position": [0, 0, 4], "intensity": [10, 20, 30] },
    { "type": "spot", "position": [0, -3, 3], "direction": [0, 1, -1], "intensity": 100,
      "cone_angle": 30, "cone_falloff": 0.2 }
  ],
  "environment": { "map": "sky.exr", "strength": 0.5, "rotate_z": 90 },
  "volume": [
    { "file": "smoke.vdb", "density_grid": "dens", "temperature_grid": "temperature",
      "transform": { "translate": [1, 2, 3], "rotate": [0, 0, 90], "scale": 2 },
      "material": { "density": 3, "anisotropy": 0.2 } },
    { "file": "/data/fire.vdb",
      "transform": { "matrix": [[2, 0, 0, 1], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]] },
      "material": { "sigma_s": 1,
                    "phase": { "type": "hg_mix", "lobes": [{ "g": 0.8, "weight": 0.7 },
                                                           { "g": -0.2, "weight": 0.3 }] } } }
  ]
}"#;

#[test]
fn json_equals_toml() {
    let t = ok(FULL_TOML);
    let j = json(FULL_JSON).unwrap();
    assert_eq!(t, j);
    // Spot-check a few converted values.
    assert_eq!(t.render.preview, Some(PathBuf::from("/s/out/a.png")));
    assert_eq!(
        t.environment,
        EnvironmentDesc::Map {
            path: PathBuf::from("/s/sky.exr"),
            strength: 0.5,
            rotate_z_deg: 90.0
        }
    );
    assert!(matches!(t.lights[2], LightDesc::Spot { blend, .. } if blend == 0.2));
    assert_eq!(t.volumes[1].file, PathBuf::from("/data/fire.vdb"));
    assert_eq!(
        t.volumes[1].transform,
        DAffine3::from_mat3_translation(DMat3::from_diagonal(DVec3::splat(2.0)), DVec3::X)
    );
}

#[test]
fn load_picks_format_from_extension() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.toml"), FULL_TOML).unwrap();
    std::fs::write(dir.path().join("a.JSON"), FULL_JSON).unwrap();
    let t = SceneDesc::load(dir.path().join("a.toml")).unwrap();
    let j = SceneDesc::load(dir.path().join("a.JSON")).unwrap();
    assert_eq!(t, j);
    assert_eq!(t.volumes[0].file, dir.path().join("smoke.vdb"));
}

// ---------------------------------------------------------------- transforms

fn transform(inline: &str) -> DAffine3 {
    ok(&format!("{VOL}transform = {inline}\n")).volumes[0].transform
}

#[test]
fn rotate_90_about_z_maps_x_to_y() {
    let t = transform("{ rotate = [0, 0, 90] }");
    assert_eq!(t.transform_point3(DVec3::X), DVec3::Y);
    assert_eq!(t.transform_point3(DVec3::Y), -DVec3::X);
    assert_eq!(t.transform_point3(DVec3::Z), DVec3::Z);
}

#[test]
fn translate_after_scale() {
    // translate · scale: (1,0,0) scaled by 2 then moved by (1,2,3).
    let t = transform("{ translate = [1, 2, 3], scale = 2 }");
    assert_eq!(t.transform_point3(DVec3::X), DVec3::new(3.0, 2.0, 3.0));
    assert_eq!(t.transform_point3(DVec3::ZERO), DVec3::new(1.0, 2.0, 3.0));
    let t = transform("{ translate = [1, 0, 0], scale = [1, 2, 3] }");
    assert_eq!(t.transform_point3(DVec3::ONE), DVec3::new(2.0, 2.0, 3.0));
}

#[test]
fn composition_is_translate_rz_ry_rx_scale() {
    // Hand-computed: S = diag(1,2,3); Rx(90): y->z, z->-y; Rz(90): x->y, y->-x.
    // e_x -> (1,0,0) -> (1,0,0) -> (0,1,0)
    // e_y -> (0,2,0) -> (0,0,2) -> (0,0,2)
    // e_z -> (0,0,3) -> (0,-3,0) -> (3,0,0)
    let expected = DAffine3::from_cols(
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(0.0, 0.0, 2.0),
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(10.0, 0.0, 0.0),
    );
    let t = transform("{ translate = [10, 0, 0], rotate = [90, 0, 90], scale = [1, 2, 3] }");
    assert_eq!(t, expected);
    // The same matrix written row-major.
    let m = transform("{ matrix = [[0, 0, 3, 10], [1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 0, 1]] }");
    assert_eq!(m, expected);
    // Ry(90) maps z to x (Blender: +Y rotation tilts +Z towards +X).
    let ry = transform("{ rotate = [0, 90, 0] }");
    assert_eq!(ry.transform_vector3(DVec3::Z), DVec3::X);
    // A general angle: X first, then Y, then Z.
    let t = transform("{ rotate = [30, 45, 60] }");
    let (a, b, c) = (30f64.to_radians(), 45f64.to_radians(), 60f64.to_radians());
    let hand = DMat3::from_rotation_z(c) * DMat3::from_rotation_y(b) * DMat3::from_rotation_x(a);
    assert!(t.matrix3.abs_diff_eq(hand, 1e-12));
    assert_eq!(t.translation, DVec3::ZERO);
}

// ---------------------------------------------------------------- validation

#[test]
fn error_principled_mixed_with_raw() {
    assert_eq!(
        toml_err(&format!("{VOL}[volume.material]\ndensity = 1\nsigma_s = 2\n")),
        "scene.toml:5: key 'sigma_s' in [volume.material]: cannot be mixed with Principled Volume \
         key 'density' (use either the Principled keys or the raw sigma_s/sigma_a/emission/phase keys)"
    );
}

#[test]
fn error_width_zero() {
    assert_eq!(
        toml_err(&format!("[render]\nwidth = 0\n{VOL}")),
        "scene.toml:2: key 'width' in [render]: must be in [1, 65536], got 0"
    );
}

#[test]
fn error_height_too_large() {
    assert_eq!(
        toml_err(&format!("[render]\nspp = 1\nheight = 65537\n{VOL}")),
        "scene.toml:3: key 'height' in [render]: must be in [1, 65536], got 65537"
    );
}

#[test]
fn error_spp_zero() {
    assert_eq!(
        toml_err(&format!("[render]\nspp = 0\n{VOL}")),
        "scene.toml:2: key 'spp' in [render]: must be >= 1, got 0"
    );
}

#[test]
fn photon_keys() {
    use vdbphoton::integrator::photon::{Estimate, PhotonSettings, Sky};
    let want = PhotonSettings {
        photons: Some(5000),
        k: Some(12),
        radius: Some(0.25),
        alpha: Some(0.5),
        step: Some(0.01),
        estimate: Estimate::Point,
        sky: Sky::Auto,
    };
    let keys =
        "photons = 5000\nk = 12\nradius = 0.25\nalpha = 0.5\nstep = 0.01\nestimate = \"point\"\n";
    // The photon integrator's own table.
    let s = ok(&format!(
        "[render]\nintegrator = \"photon\"\n[render.photon]\n{keys}{VOL}"
    ));
    assert_eq!(s.render.integrator, "photon");
    assert_eq!(PhotonSettings::of(&s).unwrap(), want);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // Today's flat keys still work, with a deprecation warning.
    let flat = ok(&format!("[render]\nintegrator = \"photon\"\n{keys}{VOL}"));
    assert_eq!(PhotonSettings::of(&flat).unwrap(), want);
    assert_eq!(flat.render.settings, s.render.settings);
    assert_eq!(flat.warnings.len(), 1);
    assert!(
        flat.warnings[0].contains("[render.photon]") && flat.warnings[0].contains("deprecated"),
        "{}",
        flat.warnings[0]
    );
    // JSON too.
    let j = json(
        r#"{"render": {"integrator": "photon", "photon": {"k": 12, "estimate": "point"}}, "volume": [{"file": "a.vdb"}]}"#,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let p = PhotonSettings::of(&j).unwrap();
    assert_eq!((p.k, p.estimate), (Some(12), Estimate::Point));
    for (text, want) in [
        ("photons = 0", "key 'photons' in [render.photon]: must be in [1, 268435456], got 0 (photons per pass; each takes about 100 bytes)"),
        ("k = 0", "key 'k' in [render.photon]: must be in [1, 1024], got 0"),
        ("k = 1.5", "key 'k' in [render.photon]: must be an integer, got a number"),
        ("radius = -1.0", "key 'radius' in [render.photon]: must be in (0, 340282346638528860000000000000000000000], got -1"),
        ("alpha = 1.5", "key 'alpha' in [render.photon]: must be in (0, 1], got 1.5"),
        ("step = 0.0", "key 'step' in [render.photon]: must be in (0, 340282346638528860000000000000000000000], got 0"),
    ] {
        // In the table: the line of the key.
        assert_eq!(
            toml_err(&format!("[render.photon]\n\n{text}\n{VOL}")),
            format!("scene.toml:3: {want}")
        );
        // A flat key: its line in [render].
        let flat = toml_err(&format!("[render]\n{text}\n{VOL}"));
        assert!(flat.starts_with("scene.toml:2: key '"), "{flat}");
        assert!(flat.ends_with(want.split_once(": ").unwrap().1), "{flat}");
    }
    assert!(toml_err(&format!("[render.photon]\nestimate = \"cone\"\n{VOL}")).contains("beam"));
    // Who carries the sky's light: by default camera paths for a constant
    // sky and photons for a map; or either.
    for (text, want) in [
        ("photons", Sky::Photons),
        ("paths", Sky::Paths),
        ("auto", Sky::Auto),
    ] {
        let sky = ok(&format!("[render.photon]\nsky = \"{text}\"\n{VOL}"));
        assert_eq!(PhotonSettings::of(&sky).unwrap().sky, want);
    }
    let e = toml_err(&format!("[render.photon]\nsky = \"both\"\n{VOL}"));
    assert!(
        e.starts_with("scene.toml:2: key 'sky' in [render.photon]")
            && e.contains("auto, paths, photons"),
        "{e}"
    );
    let e = toml_err(&format!("[render]\nintegrator = \"bdpt\"\n{VOL}"));
    assert!(
        e.starts_with("scene.toml:2: ") && e.contains("auto, path, photon"),
        "{e}"
    );
    let e = toml_err(&format!("[render.photon]\nkk = 3\n{VOL}"));
    assert!(
        e.starts_with("scene.toml:2: ") && e.contains("photons, k, radius"),
        "{e}"
    );
    let e = toml_err(&format!("[render.bdpt]\nk = 3\n{VOL}"));
    assert!(e.contains("no integrator 'bdpt'"), "{e}");
    let e = toml_err(&format!("[render.path]\nk = 3\n{VOL}"));
    assert!(e.contains("no settings"), "{e}");
    let e = toml_err(&format!("[render]\nk = 3\n[render.photon]\nk = 4\n{VOL}"));
    assert!(e.contains("given twice"), "{e}");
}

#[test]
fn error_vfov_out_of_range() {
    assert_eq!(
        toml_err(&format!("[camera]\nvfov = 180\n{VOL}")),
        "scene.toml:2: key 'vfov' in [camera]: must be in (0, 180), got 180"
    );
    assert!(toml_err(&format!("[camera]\nvfov = 0\n{VOL}")).contains("'vfov'"));
}

#[test]
fn error_camera_position_equals_look_at() {
    assert_eq!(
        toml_err(&format!(
            "[camera]\nposition = [1, 1, 1]\nlook_at = [1, 1, 1]\n{VOL}"
        )),
        "scene.toml:3: key 'look_at' in [camera]: must differ from 'position' (both are [1, 1, 1])"
    );
}

#[test]
fn error_up_parallel_to_view() {
    assert_eq!(
        toml_err(&format!(
            "[camera]\nposition = [0, 0, 5]\nup = [0, 0, 2]\n{VOL}"
        )),
        "scene.toml:3: key 'up' in [camera]: must not be zero or parallel to the view direction \
         look_at - position = [0, 0, -5]"
    );
}

#[test]
fn error_sun_direction_zero() {
    assert_eq!(
        toml_err(&format!(
            "[[light]]\ntype = \"sun\"\ndirection = [0, 0, 0]\nirradiance = 1\n{VOL}"
        )),
        "scene.toml:3: key 'direction' in [[light]]: must not be the zero vector"
    );
}

#[test]
fn error_sun_angle_out_of_range() {
    assert_eq!(
        toml_err(&format!(
            "[[light]]\ntype = \"sun\"\ndirection = [0, 0, 1]\nirradiance = 1\nangle = 180\n{VOL}"
        )),
        "scene.toml:5: key 'angle' in [[light]]: must be in [0, 180), got 180"
    );
}

#[test]
fn error_negative_irradiance() {
    assert_eq!(
        toml_err(&format!(
            "[[light]]\ntype = \"sun\"\ndirection = [0, 0, 1]\nirradiance = [1, -1, 1]\n{VOL}"
        )),
        "scene.toml:4: key 'irradiance' in [[light]]: must be >= 0, got [1, -1, 1]"
    );
}

#[test]
fn error_infinite_intensity() {
    assert_eq!(
        toml_err(&format!(
            "{VOL}[[light]]\ntype = \"point\"\nposition = [0, 0, 1]\nintensity = inf\n"
        )),
        "scene.toml:6: key 'intensity' in [[light]]: must be finite numbers, got [inf, inf, inf]"
    );
}

#[test]
fn error_spot_blend_out_of_range() {
    assert_eq!(
        toml_err(&format!(
            "[[light]]\ntype = \"spot\"\nposition = [0, 0, 1]\ndirection = [0, 0, -1]\n\
             intensity = 1\nblend = 1.5\n{VOL}"
        )),
        "scene.toml:6: key 'blend' in [[light]]: must be in [0, 1], got 1.5"
    );
}

#[test]
fn error_key_of_another_light_type() {
    assert_eq!(
        toml_err(&format!(
            "[[light]]\ntype = \"point\"\nposition = [0, 0, 1]\nintensity = 1\nangle = 2\n{VOL}"
        )),
        "scene.toml:5: key 'angle' in [[light]]: not a key of a \"point\" light \
         (expected one of: type, position, intensity)"
    );
}

#[test]
fn error_missing_light_key() {
    assert_eq!(
        toml_err(&format!("{VOL}[[light]]\ntype = \"sun\"\nirradiance = 1\n")),
        "scene.toml:3: key 'direction' in [[light]]: missing (required for a \"sun\" light)"
    );
}

#[test]
fn error_anisotropy_out_of_range() {
    assert_eq!(
        toml_err(&format!("{VOL}[volume.material]\nanisotropy = 1.5\n")),
        "scene.toml:4: key 'anisotropy' in [volume.material]: must be in [-1, 1], got 1.5"
    );
}

#[test]
fn error_phase_g_out_of_range() {
    assert_eq!(
        toml_err(&format!(
            "{VOL}[volume.material]\nsigma_s = 1\nphase = {{ type = \"schlick\", g = -1.25 }}\n"
        )),
        "scene.toml:5: key 'phase.g' in [volume.material]: must be in [-1, 1], got -1.25"
    );
}

#[test]
fn error_mix_weight_negative() {
    assert_eq!(
        toml_err(&format!(
            "{VOL}[volume.material]\nsigma_s = 1\n[volume.material.phase]\ntype = \"hg_mix\"\n\
             lobes = [\n  {{ g = 0.5, weight = 1 }},\n  {{ g = 0.1, weight = -0.5 }},\n]\n"
        )),
        "scene.toml:9: key 'phase.lobes[1].weight' in [volume.material]: must be >= 0, got -0.5"
    );
}

#[test]
fn error_mix_weights_sum_zero() {
    assert_eq!(
        toml_err(&format!(
            "{VOL}[volume.material]\nsigma_s = 1\nphase = {{ type = \"hg_mix\", lobes = [{{ g = 0.5, weight = 0 }}] }}\n"
        )),
        "scene.toml:5: key 'phase.lobes' in [volume.material]: weights must have a positive sum, got 0"
    );
}

#[test]
fn error_nan() {
    assert_eq!(
        toml_err(&format!("{VOL}[volume.material]\ndensity = nan\n")),
        "scene.toml:4: key 'density' in [volume.material]: must be a finite number, got NaN"
    );
    assert!(
        toml_err(&format!("[camera]\nposition = [0, nan, 0]\n{VOL}"))
            .starts_with("scene.toml:2: key 'position' in [camera]: must be finite numbers")
    );
}

#[test]
fn error_no_volume() {
    assert_eq!(
        toml_err("[render]\nwidth = 10\n"),
        "scene.toml: no [[volume]] and no [[mesh]]: a scene needs something to render"
    );
}

#[test]
fn error_transform_matrix_last_row() {
    assert_eq!(
        toml_err(&format!(
            "{VOL}[volume.transform]\nmatrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]\n"
        )),
        "scene.toml:4: key 'matrix' in [volume.transform]: last row must be [0, 0, 0, 1], got [0.0, 0.0, 1.0, 1.0]"
    );
}

/// A fixed-length array of any other length is refused, in TOML as in JSON
/// (the TOML reader alone would take the first three numbers of
/// `[0, -3, 1, 99, "x"]` and drop the rest).
#[test]
fn arrays_of_the_wrong_length_are_refused() {
    let cases = [
        (
            "[camera]\nposition = [0, -3, 1, 99, \"x\"]\n",
            "scene.toml:2: key 'position' in [camera]: invalid length 5, expected an array of length 3",
        ),
        (
            "[camera]\nlook_at = [0, 0]\n",
            "scene.toml:2: key 'look_at' in [camera]: invalid length 2, expected an array of length 3",
        ),
        (
            "[[light]]\ntype = \"sun\"\nirradiance = 1\ndirection = [0, 0, 1, 1]\n",
            "scene.toml:4: key 'direction' in [[light]]: invalid length 4, expected an array of length 3",
        ),
        (
            "[volume.transform]\nmatrix = [[1, 0, 0, 0, 7], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
            "scene.toml:4: key 'matrix[0]' in [volume.transform]: invalid length 5, expected an array of length 4",
        ),
        (
            "[volume.transform]\nmatrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, 1]]\n",
            "scene.toml:4: key 'matrix' in [volume.transform]: invalid length 5, expected an array of length 4",
        ),
        (
            "temperature_from_flame = [1.5, 3.0, 4.5]\n",
            "scene.toml:3: key 'temperature_from_flame' in [[volume]]: invalid length 3, expected an array of length 2",
        ),
    ];
    for (body, want) in cases {
        let text = if body.starts_with("[volume") || !body.starts_with('[') {
            format!("{VOL}{body}")
        } else {
            format!("{body}{VOL}")
        };
        let got = toml_err(&text);
        assert_eq!(got, want, "{text}");
    }
    let bounds = toml_err(&format!("{VOL}bounds = [[0, 0, 0, 0], [1, 1, 1]]\n"));
    assert!(
        bounds.starts_with("scene.toml:3: key 'bounds[0]' in [[volume]]: invalid length 4"),
        "{bounds}"
    );
    let j = err(json(
        "{\"camera\": {\"position\": [0, -3, 1, 99]}, \"volume\": [{\"file\": \"a.vdb\"}]}",
    ));
    assert_eq!(
        j,
        "scene.json:1: key 'position' in [camera]: invalid length 4, expected an array of length 3"
    );
}

#[test]
fn error_transform_matrix_and_trs() {
    assert!(toml_err(&format!(
        "{VOL}transform = {{ scale = 2, matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]] }}\n"
    ))
    .starts_with("scene.toml:3: key 'scale' in [volume.transform]: cannot be combined with 'matrix'"));
}

#[test]
fn error_transform_singular() {
    assert_eq!(
        toml_err(&format!("{VOL}transform = {{ scale = [1, 0, 1] }}\n")),
        "scene.toml:3: key 'transform' in [[volume]]: is singular (a zero scale or degenerate matrix)"
    );
}

#[test]
fn error_environment_map_and_radiance() {
    assert_eq!(
        toml_err(&format!(
            "[environment]\nmap = \"sky.exr\"\nradiance = 1\n{VOL}"
        )),
        "scene.toml:3: key 'radiance' in [environment]: give either 'radiance' or 'map', not both"
    );
}

#[test]
fn error_on_second_volume_names_its_line() {
    assert_eq!(
        toml_err(&format!(
            "{VOL}\n{VOL}[volume.material]\ntemperature = -5\n"
        )),
        "scene.toml:7: key 'temperature' in [volume.material]: must be >= 0, got -5"
    );
}

#[test]
fn validation_error_in_json_names_line() {
    assert_eq!(
        err(json(
            "{\n \"volume\": [{\"file\": \"a\",\n  \"material\": {\"anisotropy\": 2}}]\n}"
        )),
        "scene.json:3: key 'anisotropy' in [volume.material]: must be in [-1, 1], got 2"
    );
}

#[test]
fn validate_again_after_cli_override() {
    let mut scene = ok(VOL);
    scene.render.width = 0;
    let e = scene.validate().unwrap_err();
    assert_eq!(
        e.path,
        vec![PathSeg::Key("render".into()), PathSeg::Key("width".into())]
    );
    assert_eq!(e.key_path(), "render.width");
    assert_eq!(
        e.to_string(),
        "key 'width' in [render]: must be in [1, 65536], got 0"
    );
    scene.render.width = 1920;
    scene.render.spp = 1;
    scene.render.output = PathBuf::from("elsewhere.exr");
    assert_eq!(scene.validate(), Ok(()));
}

// ---------------------------------------------------------------- syntax and schema errors

#[test]
fn unknown_key_in_toml_names_key_and_line() {
    let text = format!("[render]\nwidth = 8\n\n{VOL}densty = 1\n");
    assert_eq!(
        toml_err(&text),
        "scene.toml:6: unknown key 'densty' in [[volume]] (expected one of: file, density_grid, \
         temperature_grid, flame_grid, color_grid, blackbody_interpolation, transform, material, bounds, \
         frame_offset, temperature_from_flame, velocity_grid, velocity_scale, velocity_unit)"
    );
    let text = format!("{VOL}[volume.material]\n\ndensity = 1\nanisotropi = 0.5\n");
    let msg = toml_err(&text);
    assert!(
        msg.starts_with(
            "scene.toml:6: unknown key 'anisotropi' in [volume.material] (expected one of: density, color,"
        ),
        "{msg}"
    );
    assert_eq!(
        toml_err(&format!("{VOL}material = {{ phase = {{ type = \"hg\", gg = 1 }} }}\n")),
        "scene.toml:3: unknown key 'phase.gg' in [volume.material] (expected one of: type, g, lobes, backscatter, ior, alpha, diameter; did you mean 'g'?)"
    );
    assert_eq!(
        toml_err(&format!("lights = 1\n{VOL}")),
        "scene.toml:1: unknown key 'lights' at top level (expected one of: render, camera, light, \
         environment, volume, mesh; did you mean 'light'?)"
    );
}

#[test]
fn unknown_key_in_json_names_key_and_line() {
    assert_eq!(
        err(json("{\n  \"render\": {\"width\": 8},\n  \"volume\": [\n    {\"file\": \"a\", \"densty\": 1}\n  ]\n}")),
        "scene.json:4: unknown key 'densty' in [[volume]] (expected one of: file, density_grid, \
         temperature_grid, flame_grid, color_grid, blackbody_interpolation, transform, material, bounds, \
         frame_offset, temperature_from_flame, velocity_grid, velocity_scale, velocity_unit)"
    );
    assert_eq!(
        err(json("{\"volume\": [{\"file\": \"a\"}],\n \"camera\": {\"fov\": 3}}")),
        "scene.json:2: unknown key 'fov' in [camera] (expected one of: position, look_at, up, vfov, \
         focal_length, sensor_width, sensor_height, sensor_fit, shift_x, shift_y, matrix, location, \
         rotation, framing, direction; did you mean 'vfov'?)"
    );
}

#[test]
fn type_errors_name_key_and_line() {
    assert_eq!(
        toml_err(&format!("[render]\nspp = 8\nwidth = \"wide\"\n{VOL}")),
        "scene.toml:3: key 'width' in [render]: invalid type: string \"wide\", expected u32"
    );
    assert_eq!(
        toml_err(&format!("[render]\nwidth = 320.5\n{VOL}")),
        "scene.toml:2: key 'width' in [render]: invalid type: floating point `320.5`, expected u32"
    );
    assert_eq!(
        toml_err(&format!("{VOL}[volume.material]\ncolor = [1, 2]\n")),
        "scene.toml:4: key 'color' in [volume.material]: invalid length 2, expected an array of 3 \
         numbers or a single number"
    );
    assert_eq!(
        err(json(
            "{\"volume\": [{\"file\": \"a\"}],\n\"render\": {\"width\": \"wide\"}}"
        )),
        "scene.json:2: key 'width' in [render]: invalid type: string \"wide\", expected u32"
    );
}

#[test]
fn unknown_enum_value_and_missing_required_key() {
    assert_eq!(
        toml_err(&format!("{VOL}[[light]]\ntype = \"area\"\n")),
        "scene.toml:4: unknown value 'area' for key 'type' in [[light]] (expected one of: sun, point, spot)"
    );
    assert_eq!(
        toml_err(&format!("{VOL}\n[[volume]]\ndensity_grid = \"d\"\n")),
        "scene.toml:4: missing key 'file' in [[volume]]"
    );
}

#[test]
fn malformed_toml() {
    assert_eq!(
        toml_err("[render]\nwidth = 3\nwidth = 4\n"),
        "scene.toml:3: invalid TOML: duplicate key (at 'width')"
    );
    let msg = toml_err("[render\nwidth = 3\n");
    assert!(msg.starts_with("scene.toml:1: invalid TOML: "), "{msg}");
}

#[test]
fn malformed_json() {
    assert_eq!(
        err(json("{\"volume\": [{\"file\": \"a\"}\n")),
        "scene.json:2: invalid JSON: EOF while parsing a list (column 0)"
    );
    assert_eq!(
        err(json("\n[1, 2]")),
        "scene.json:2: invalid JSON scene: the top level must be an object { ... }"
    );
}

#[test]
fn single_brackets_for_an_array_table() {
    assert_eq!(
        toml_err("[volume]\nfile = \"a.vdb\"\n"),
        "scene.toml:1: key 'volume' at top level: invalid type: map, expected a sequence \
         (write [[volume]] with double brackets)"
    );
}

#[test]
fn truncated_files_never_panic_and_give_one_line() {
    for (text, format) in [
        (FULL_TOML, SceneFormat::Toml),
        (FULL_JSON, SceneFormat::Json),
    ] {
        for end in (0..text.len()).filter(|&i| text.is_char_boundary(i)) {
            if let Err(e) = SceneDesc::from_str(&text[..end], format, "/s") {
                let msg = e.to_string();
                assert!(
                    msg.starts_with("<string>") && !msg.contains('\n'),
                    "{msg:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------- files

fn load_err(path: &Path) -> String {
    let msg = SceneDesc::load(path).unwrap_err().to_string();
    assert!(!msg.contains('\n'), "{msg:?}");
    assert!(msg.starts_with(&path.display().to_string()), "{msg}");
    msg
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.toml");
    let msg = load_err(&path);
    assert!(
        msg.starts_with(&format!("{}: cannot read scene file: ", path.display())),
        "{msg}"
    );
    assert!(matches!(
        SceneDesc::load(&path),
        Err(SceneError::Read { .. })
    ));
}

#[test]
fn directory_instead_of_file() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(
        load_err(dir.path()),
        format!("{}: is a directory, not a scene file", dir.path().display())
    );
}

#[test]
fn empty_file() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["empty.toml", "empty.json"] {
        let path = dir.path().join(name);
        std::fs::write(&path, "\n").unwrap();
        assert_eq!(
            load_err(&path),
            format!(
                "{}: no [[volume]] and no [[mesh]]: a scene needs something to render",
                path.display()
            )
        );
    }
}

#[test]
fn malformed_file_on_disk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, "[render]\nwidth = = 3\n").unwrap();
    let msg = load_err(&path);
    assert!(
        msg.starts_with(&format!("{}:2: invalid TOML: ", path.display())),
        "{msg}"
    );
    let path = dir.path().join("bin.toml");
    std::fs::write(&path, b"[render]\n\xff\xfe\n").unwrap();
    assert_eq!(
        load_err(&path),
        format!("{}:2: file is not valid UTF-8 text", path.display())
    );
    assert_eq!(SceneDesc::load(&path).unwrap_err().line(), Some(2));
}

/// `[[mesh]]`: the file resolved against the scene, a transform, Blender's
/// holdout, shadow catcher and ray visibility (every key optional, true by
/// default), and `[render] film_transparent`.
#[test]
fn meshes_and_a_transparent_film() {
    let scene = ok(&format!(
        "[render]\nfilm_transparent = true\n{VOL}[[mesh]]\nfile = \"m/ground.ply\"\nname = \"Ground\"\nshadow_catcher = true\ntransform = {{ translate = [0, 0, -1] }}\n[[mesh]]\nfile = \"ball.obj\"\nholdout = true\nvisibility = {{ shadow = false, volume_scatter = false }}\n"
    ));
    assert!(scene.render.film_transparent);
    let [g, b] = &scene.meshes[..] else {
        panic!("two meshes")
    };
    assert_eq!(g.file, PathBuf::from("/s/m/ground.ply"));
    assert_eq!(g.name.as_deref(), Some("Ground"));
    assert!(g.shadow_catcher && !g.holdout);
    assert_eq!(g.transform.translation, glam::DVec3::new(0.0, 0.0, -1.0));
    assert_eq!(g.visibility, vdbphoton::scene::RayVisibility::default());
    assert!(b.holdout && !b.shadow_catcher && b.name.is_none());
    let v = b.visibility;
    assert!(v.camera && v.diffuse && v.glossy && v.transmission);
    assert!(!v.shadow && !v.volume_scatter);
}

#[test]
fn error_mesh_keys() {
    assert_eq!(
        toml_err(&format!("{VOL}[[mesh]]\nfile = \"a.ply\"\nvisibility = {{ reflection = false }}\n")),
        "scene.toml:5: unknown key 'reflection' in [mesh.visibility] (expected one of: camera, shadow, diffuse, glossy, transmission, volume_scatter)"
    );
    assert_eq!(
        toml_err(&format!(
            "{VOL}[[mesh]]\nfile = \"a.ply\"\ntransform = {{ scale = [1, 0, 1] }}\n"
        )),
        "scene.toml:5: key 'transform' in [[mesh]]: is singular (a zero scale or degenerate matrix)"
    );
    assert!(toml_err(&format!("{VOL}[[mesh]]\nholdout = true\n")).contains("file"));
}
