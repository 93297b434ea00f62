//! Blender's camera against Cycles: sensor fit (auto, horizontal,
//! vertical), focal length and sensor size, lens shift, a camera given by
//! `matrix`, by `location` + `rotation` and by a field of view, on
//! landscape and portrait images. The target is 26 small emissive balls
//! (`tests/data/camera`, made by `make_blobs.py`); Cycles 5.0.1 rendered
//! each scene at 2048 spp and `cycles_centroids.json` holds each ball's
//! intensity-weighted centroid in Cycles' image. Cycles' centroids agree
//! with Blender's own projection of the ball centres within 0.015 px
//! (`tests/data/camera/README.md`), so a tenth of a pixel is a wide margin
//! for a right camera, while a half-pixel convention (0.71 px), shift in
//! units of the wrong side (8-13 px) or the wrong sensor side in auto fit
//! (12-16 px) fail by far.

use glam::Vec3;
use std::path::{Path, PathBuf};
use vdbphoton::render::passes::{render, Settings};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::{make_camera, World};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/camera");

const SCENES: [&str; 9] = [
    "land_auto",
    "land_vertical",
    "land_horizontal_shift",
    "land_vertical_shift",
    "land_vfov_shift",
    "port_auto",
    "port_horizontal",
    "port_vertical",
    "port_auto_shift",
];

fn json(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(Path::new(DATA).join(name)).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn scene(name: &str) -> SceneDesc {
    SceneDesc::load(PathBuf::from(DATA).join(format!("{name}.toml"))).unwrap()
}

/// Each ball's Cycles centroid (pixels, y down) in scene `name`.
fn cycles(name: &str) -> Vec<(usize, [f64; 2])> {
    json("cycles_centroids.json")[name]["blobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            let c = &b["cycles"];
            (
                b["ball"].as_u64().unwrap() as usize,
                [c[0].as_f64().unwrap(), c[1].as_f64().unwrap()],
            )
        })
        .collect()
}

#[test]
fn ball_centres_project_where_cycles_shows_them() {
    let blobs = json("blobs.json");
    let centres: Vec<Vec3> = blobs["centres"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let v: Vec<f32> = c
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap() as f32)
                .collect();
            Vec3::new(v[0], v[1], v[2])
        })
        .collect();
    for name in SCENES {
        let d = scene(name);
        let cam = make_camera(&d.camera, d.render.width, d.render.height, &[]).unwrap();
        let mut worst = 0.0f64;
        let expected = cycles(name);
        assert!(expected.len() >= 20, "{name}");
        for (ball, c) in expected {
            let p = cam.project(centres[ball]).expect("in front of the camera");
            let err = ((p.x as f64 - c[0]).powi(2) + (p.y as f64 - c[1]).powi(2)).sqrt();
            worst = worst.max(err);
        }
        // Measured: at most 0.016 px (Cycles' own noise and the balls'
        // perspective, see the module docs).
        assert!(
            worst < 0.05,
            "{name}: a ball is {worst:.4} px from Cycles' centroid"
        );
    }
}

/// Intensity-weighted centroids of the blobs of an image (`centroids.py`):
/// pixels above 1e-3 of the brightest, 8-connected, blobs touching the
/// border left out.
fn centroids(w: usize, h: usize, l: &[f32]) -> Vec<[f64; 2]> {
    let max = l.iter().copied().fold(0.0f32, f32::max);
    let lit: Vec<bool> = l.iter().map(|&v| v > 1e-3 * max).collect();
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    for start in 0..w * h {
        if !lit[start] || seen[start] {
            continue;
        }
        let (mut sum, mut sx, mut sy, mut border) = (0.0f64, 0.0f64, 0.0f64, false);
        let mut stack = vec![start];
        seen[start] = true;
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            border |= x == 0 || y == 0 || x == w - 1 || y == h - 1;
            let v = l[i] as f64;
            sum += v;
            sx += v * (x as f64 + 0.5);
            sy += v * (y as f64 + 0.5);
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if lit[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if !border {
            out.push([sx / sum, sy / sum]);
        }
    }
    out
}

#[test]
fn rendered_balls_land_on_cycles_pixels() {
    // A landscape and a portrait image, each with a shift, rendered by the
    // path tracer (emission only, so a few hundred samples give centroids
    // good to a few hundredths of a pixel).
    for name in ["land_vertical_shift", "port_auto_shift"] {
        let mut d = scene(name);
        d.render.spp = 256;
        let world = World::load(&d).unwrap();
        let s = Settings {
            width: d.render.width,
            height: d.render.height,
            spp: d.render.spp,
            seed: 3,
            max_bounces: 0,
        };
        let film = render(&world, &s, &|_, _| {});
        let l: Vec<f32> = film
            .mean_rgb()
            .iter()
            .map(|c| c.element_sum() / 3.0)
            .collect();
        let ours = centroids(s.width as usize, s.height as usize, &l);
        let theirs = cycles(name);
        assert!(
            ours.len() >= theirs.len(),
            "{name}: {} blobs found",
            ours.len()
        );
        let mut worst = 0.0f64;
        for (_, c) in &theirs {
            let nearest = ours
                .iter()
                .map(|o| ((o[0] - c[0]).powi(2) + (o[1] - c[1]).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(nearest);
        }
        assert!(worst < 0.1, "{name}: a blob is {worst:.4} px from Cycles'");
    }
}
