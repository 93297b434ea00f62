//! `vdbphoton render` and `view`: the scene (or a quick look at a .vdb),
//! the command line's overrides, the frames, and the lines a farm log
//! reads. The rendering is the library's (`vdbphoton::frames`).

use crate::args::RenderArgs;
use crate::reporter::{summary_line, CliReporter};
use std::time::Instant;
use vdbphoton::{Error, Result};

pub fn render(a: RenderArgs, quick_look: bool) -> Result<()> {
    use vdbphoton::frames::{render_job, FrameJob, FrameOutcome};
    use vdbphoton::render::{Overrides, RenderOptions};
    let t_start = Instant::now();
    if let Some(v) = &a.addon_version {
        check_addon(v)?;
    }
    let reporter = CliReporter::new(a.quiet, a.progress == "json");
    let quick_look = quick_look || vdbphoton::quicklook::is_vdb(&a.scene);
    let mut desc = if quick_look {
        let (desc, notes) = vdbphoton::quicklook::scene_for(&a.scene)?;
        if !a.quiet {
            for n in notes {
                eprintln!("quick look: {n}");
            }
        }
        desc
    } else {
        vdbphoton::render::load_scene(&a.scene)?
    };
    Overrides {
        output: a.output,
        preview: a.preview,
        no_preview: a.no_preview,
        spp: a.spp,
        seed: a.seed,
        max_bounces: a.max_bounces,
        width: a.width,
        height: a.height,
        exposure: a.exposure,
        integrator: a.integrator,
        aovs: a.aovs,
        denoise: a.denoise,
        denoise_quality: a.denoise_quality,
        resume: a.resume,
    }
    .apply(&mut desc, &a.scene)?;
    let region = a
        .region
        .as_deref()
        .map(|s| {
            vdbphoton::film::Region::parse(s, desc.render.width, desc.render.height)
                .map_err(Error::Argument)
        })
        .transpose()?;
    let opts = RenderOptions {
        threads: a.threads.map(|t| t as usize),
        time_limit: a.time,
        checkpoint: a.checkpoint,
        no_resume_state: a.no_resume_state,
        max_memory: a.max_memory,
        attributes: vec![("vdbphoton/scene".to_string(), a.scene.display().to_string())],
        region,
        tile: a.tile,
        view: a.view.unwrap_or_default(),
    };
    let job = FrameJob {
        frames: a.frames.map(|f| f.0).or(a.frame.map(|f| vec![f])),
        skip_existing: a.skip_existing,
    };
    let report = render_job(&desc, &job, &opts, &reporter).map_err(|e| {
        // Errors about the scene's inputs say which scene.
        match e {
            e @ (Error::Scene(_) | Error::Interrupted { .. } | Error::Argument(_)) => e,
            e if quick_look => e,
            e => e.context(a.scene.display().to_string()),
        }
    })?;
    // The summary is printed even with --quiet: it is the line a farm log
    // wants.
    let total = t_start.elapsed().as_secs_f64();
    match report.frames.as_slice() {
        [(None, FrameOutcome::Written(s))] => {
            eprintln!("{} (total {total:.2} s)", summary_line(s))
        }
        [(None, FrameOutcome::Skipped(p))] => {
            eprintln!("skipped: '{}' exists", p.display())
        }
        _ => eprintln!("frames: {} in {total:.2} s", report.tally()),
    }
    if !report.ok() {
        let failed = report.failed();
        return Err(Error::Argument(format!(
            "{} of {} frames failed: {}",
            failed.len(),
            report.frames.len(),
            vdbphoton::sequence::format_frames(&failed)
        )));
    }
    Ok(())
}

/// The major version of the Blender add-on (tools/blender/vdbphoton/,
/// `binary.ADDON_VERSION`, sent as `--addon-version`) whose progress
/// stream and options this binary speaks; the add-on checks the binary's
/// `--version` the other way.
const ADDON_MAJOR: u32 = 1;

/// Refuses to render for an add-on of another major version.
fn check_addon(version: &str) -> Result<()> {
    let major = version
        .split('.')
        .next()
        .and_then(|m| m.parse::<u32>().ok());
    if major == Some(ADDON_MAJOR) {
        return Ok(());
    }
    Err(Error::Argument(format!(
        "the Blender add-on is version {version}; this vdbphoton ({}) speaks to add-on {ADDON_MAJOR}.x: install the add-on that comes with this binary (the extension tools/blender/build_extension.py builds)",
        env!("CARGO_PKG_VERSION")
    )))
}
