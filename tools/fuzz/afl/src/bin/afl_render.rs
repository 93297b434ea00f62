//! AFL++ target: a whole render of a tiny image from a mutated scene and a
//! mutated VDB, in process, as `vdbfuzz`'s render target does through the
//! command line.
//!
//! Input: one byte for the format (even: TOML, odd: JSON), the scene text,
//! a NUL byte, then the `.vdb` file the scene reads as `input.vdb` (a NUL
//! cannot occur in a scene, so the first one splits the two). The image is
//! forced to 16 x 12 at 1 spp on one thread, with at most 4,096 photons a
//! pass, as the command line's options would; everything else is the
//! scene's.
//!
//! A crash, an abort or a panic is a finding; a refusal is fine. An
//! accepted render is a finding if its image holds a non-finite pixel or a
//! grid it read holds NaN or infinite values (`vdbfuzz`'s wrong accepts).

#[path = "../../../oracle.rs"]
#[allow(dead_code)]
mod oracle;

use vdbphoton::frames::{render_job, FrameJob};
use vdbphoton::render::{Overrides, RenderOptions, Silent};
use vdbphoton::scene::{Param, SceneDesc};

/// Photons a pass at most: a scene may ask for millions, which is work it
/// asked for, not a hang.
const MAX_PHOTONS: i64 = 4096;

fn main() {
    // OpenVDB opens files by name: the input goes to a directory of this
    // process's own, rewritten for each input.
    let dir = std::env::var_os("AFL_TARGET_TMP")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(std::env::temp_dir)
        .join(format!("afl_render_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let vdb = dir.join("input.vdb");
    let exr = dir.join("out.exr");
    afl::fuzz!(|data: &[u8]| {
        let Some((format, rest)) = vdbphoton_afl::format_and_rest(data) else {
            return;
        };
        let split = rest.iter().position(|&b| b == 0).unwrap_or(rest.len());
        let (scene, file) = (&rest[..split], rest.get(split + 1..).unwrap_or(&[]));
        // `SceneDesc::load` refuses text that is not UTF-8 before parsing.
        let Ok(text) = std::str::from_utf8(scene) else {
            return;
        };
        std::fs::write(&vdb, file).expect("scratch file");
        let _ = std::fs::remove_file(&exr);
        let Ok(mut desc) = SceneDesc::from_str_named(text, format, &dir, "input") else {
            return;
        };
        // The photon count is capped (a scene may ask for 2^28).
        let photon = desc.render.settings.entry("photon".into()).or_default();
        let photons = photon.get("photons").and_then(|p| p.as_i64());
        photon.insert(
            "photons".into(),
            Param::Int(photons.unwrap_or(MAX_PHOTONS).clamp(1, MAX_PHOTONS)),
        );
        let small = Overrides {
            output: Some(exr.clone()),
            no_preview: true,
            width: Some(16),
            height: Some(12),
            spp: Some(1),
            ..Default::default()
        };
        if small.apply(&mut desc, std::path::Path::new("input")).is_err() {
            return;
        }
        let opts = RenderOptions {
            threads: Some(1),
            max_memory: Some(1 << 30),
            ..Default::default()
        };
        let job = FrameJob {
            frames: None,
            skip_existing: false,
        };
        if render_job(&desc, &job, &opts, &Silent).is_err() {
            return;
        }
        let img = vdbphoton::image::read_exr_rgb(&exr)
            .unwrap_or_else(|e| panic!("rendered, but no readable image: {e}"));
        assert!(
            img.pixels.iter().all(|p| p.is_finite()),
            "non-finite pixels in the image"
        );
        // Grids the render read, by name, from the file it read.
        let read: Vec<&str> = desc
            .volumes
            .iter()
            .filter(|v| v.file == vdb)
            .flat_map(|v| {
                [
                    Some(v.density_grid.as_str()),
                    v.temperature_grid.as_deref(),
                    v.flame_grid.as_deref(),
                    v.color_grid.as_deref(),
                ]
            })
            .flatten()
            .collect();
        if let Ok(report) = oracle::read_vdb(&vdb) {
            let bad: Vec<&String> = report
                .nonfinite
                .iter()
                .filter(|g| read.contains(&g.as_str()))
                .collect();
            assert!(
                bad.is_empty(),
                "rendered grids with NaN or infinite values: {bad:?}"
            );
        }
    });
    // After AFL's last input (a crash leaves it; run.sh clears them all).
    let _ = std::fs::remove_dir_all(&dir);
}
