//! A scene over frames: which frames to render, each frame's inputs and
//! outputs (the frame patterns of [`crate::sequence`]), each frame's seed,
//! resuming with `--skip-existing`, and failures that do not stop the other
//! frames. Each frame is one [`render_scene`]; the CLI, the farm scripts and
//! the Flamenco job type all go through [`render_job`].

use crate::error::{Error, Result};
pub use crate::render::FrameOutcome;
use crate::render::{render_scene, RenderOptions, Reporter};
use crate::scene::{EnvironmentDesc, SceneDesc, VolumeBounds};
use crate::sequence::{format_frames, frame_seed, PathPattern};
use std::path::PathBuf;
use std::time::Instant;

/// What to render of a scene besides what it says itself.
#[derive(Debug, Clone, Default)]
pub struct FrameJob {
    /// The frames to render; `None`: the scene's `[render] frames`, or one
    /// render of the scene as it is when it names no sequence.
    pub frames: Option<Vec<u32>>,
    /// Leave frames whose EXR exists (outputs are written atomically, so
    /// an existing file is complete).
    pub skip_existing: bool,
}

/// What a job did, frame by frame (`None`: a scene rendered without a
/// frame number).
#[derive(Debug, Default)]
pub struct JobReport {
    pub frames: Vec<(Option<u32>, FrameOutcome)>,
}

impl JobReport {
    /// The frames that failed, by number.
    pub fn failed(&self) -> Vec<u32> {
        self.frames
            .iter()
            .filter(|(_, o)| matches!(o, FrameOutcome::Failed(_)))
            .filter_map(|(f, _)| *f)
            .collect()
    }
    /// What happened to the frames: `3 written, 1 skipped, 1 failed (7)`.
    pub fn tally(&self) -> String {
        let count = |f: fn(&FrameOutcome) -> bool| self.frames.iter().filter(|(_, o)| f(o)).count();
        let written = count(|o| matches!(o, FrameOutcome::Written(_)));
        let skipped = count(|o| matches!(o, FrameOutcome::Skipped(_)));
        let failed = self.failed();
        format!(
            "{written} written, {skipped} skipped, {} failed{}",
            failed.len(),
            if failed.is_empty() {
                String::new()
            } else {
                format!(" ({})", format_frames(&failed))
            }
        )
    }

    /// Whether every frame was written or skipped.
    pub fn ok(&self) -> bool {
        !self
            .frames
            .iter()
            .any(|(_, o)| matches!(o, FrameOutcome::Failed(_)))
    }
}

/// A path's pattern, with a message naming the key when it is malformed.
fn pattern(p: &std::path::Path) -> Result<PathPattern> {
    PathPattern::new(p).map_err(Error::Argument)
}

/// The scene of `frame` (and `tile`): frame patterns in volume files,
/// the environment map and the outputs replaced, and the seed derived from
/// (seed, frame), so neighbouring frames get unrelated noise and a frame
/// rendered alone is the frame of the sequence.
pub fn scene_at(desc: &SceneDesc, frame: Option<u32>, tile: Option<u32>) -> Result<SceneDesc> {
    let mut d = desc.clone();
    for v in &mut d.volumes {
        let p = pattern(&v.file)?;
        let f = match frame {
            Some(f) if p.has_frame() => Some(offset_frame(f, v.frame_offset, &v.file)?),
            f => f,
        };
        v.file = p.expand(f, None);
    }
    if let EnvironmentDesc::Map { path, .. } = &mut d.environment {
        *path = pattern(path)?.expand(frame, None);
    }
    let r = &mut d.render;
    r.output = pattern(&r.output)?.expand(frame, tile);
    if let Some(p) = &r.preview {
        r.preview = Some(pattern(p)?.expand(frame, tile));
    }
    if let Some(f) = frame {
        r.seed = frame_seed(r.seed, f);
    }
    Ok(d)
}

/// Frame `frame` of a volume read `offset` frames later (`frame_offset`).
fn offset_frame(frame: u32, offset: i64, file: &std::path::Path) -> Result<u32> {
    u32::try_from(frame as i64 + offset).map_err(|_| {
        Error::file(
            file,
            format!("frame {frame} with frame_offset {offset} is before frame 0"),
        )
    })
}

/// An input path of a scene that names a sequence, and the offset of its
/// frames.
struct Input {
    pattern: PathPattern,
    offset: i64,
}

impl Input {
    /// The file of render frame `frame`, if the offset keeps it at 0 or
    /// after.
    fn path(&self, frame: u32) -> Option<PathBuf> {
        let f = u32::try_from(frame as i64 + self.offset).ok()?;
        Some(self.pattern.expand(Some(f), None))
    }
}

/// The input paths of a scene that name a sequence.
fn sequence_inputs(desc: &SceneDesc) -> Result<Vec<Input>> {
    let mut out = Vec::new();
    for v in &desc.volumes {
        let p = pattern(&v.file)?;
        if p.has_frame() {
            out.push(Input {
                pattern: p,
                offset: v.frame_offset,
            });
        }
    }
    if let EnvironmentDesc::Map { path, .. } = &desc.environment {
        let p = pattern(path)?;
        if p.has_frame() {
            out.push(Input {
                pattern: p,
                offset: 0,
            });
        }
    }
    Ok(out)
}

/// Checks the frames and outputs of a job before anything renders, and
/// returns the frames to render (`None`: one render without a frame).
fn plan(desc: &SceneDesc, job: &FrameJob, tile: Option<u32>) -> Result<Option<Vec<u32>>> {
    let r = &desc.render;
    let inputs = sequence_inputs(desc)?;
    let output = pattern(&r.output)?;
    let preview = r.preview.as_deref().map(pattern).transpose()?;
    let frames = job.frames.clone().or_else(|| r.frames.clone());
    let sequence = inputs
        .first()
        .map(|i| i.pattern.expand(None, None))
        .or_else(|| output.has_frame().then(|| r.output.clone()))
        .or_else(|| {
            preview
                .as_ref()
                .filter(|p| p.has_frame())
                .map(|p| p.expand(None, None))
        });
    if let (None, Some(seq)) = (&frames, &sequence) {
        return Err(Error::Argument(format!(
            "'{}' names a frame sequence: give --frame N or --frames LIST (e.g. 1-40), or [render] frames in the scene",
            seq.display()
        )));
    }
    if let Some(f) = &frames {
        if f.len() > 1 {
            for (what, p) in [("output", Some(&output)), ("preview", preview.as_ref())] {
                if let Some(p) = p.filter(|p| !p.has_frame()) {
                    return Err(Error::Argument(format!(
                        "the {what} '{}' has no frame number ({{frame:04}} or ####): the {} frames would overwrite each other",
                        p.expand(None, None).display(),
                        f.len()
                    )));
                }
            }
        }
    }
    for (what, p) in [("output", Some(&output)), ("preview", preview.as_ref())] {
        if let Some(p) = p.filter(|p| p.has_tile() && tile.is_none()) {
            return Err(Error::Argument(format!(
                "the {what} '{}' holds {{tile}}, which only a --tile render fills in",
                p.expand(None, None).display()
            )));
        }
    }
    Ok(frames)
}

/// Volumes whose `bounds = "sequence"` get the box of every frame of their
/// sequence now, so automatic framing stays fixed over the frames.
fn fix_sequence_bounds(desc: &mut SceneDesc) -> Result<()> {
    for v in &mut desc.volumes {
        if v.bounds != VolumeBounds::Sequence {
            continue;
        }
        let p = pattern(&v.file)?;
        v.bounds = if p.has_frame() {
            match crate::world::sequence_file_box(&p, &v.density_grid) {
                Some(b) => VolumeBounds::Box(b),
                None => VolumeBounds::Active,
            }
        } else {
            VolumeBounds::Active
        };
    }
    Ok(())
}

/// Renders a validated scene over the frames of `job` (or once), each
/// frame to its own outputs. A frame whose input is missing or damaged
/// fails with a message naming it and the others still render; the report
/// says how each ended. An interruption (SIGINT, SIGTERM) stops the whole
/// job and is returned as an error; so is a job that cannot start (no
/// frames, outputs that would overwrite each other, no input file for any
/// frame).
pub fn render_job(
    desc: &SceneDesc,
    job: &FrameJob,
    opts: &RenderOptions,
    reporter: &dyn Reporter,
) -> Result<JobReport> {
    let tile = opts.tile.map(|t| t.0);
    let Some(frames) = plan(desc, job, tile)? else {
        let d = scene_at(desc, None, tile)?;
        let outcome = if job.skip_existing && crate::render::resume::is_finished(&d.render.output) {
            FrameOutcome::Skipped(d.render.output.clone())
        } else {
            FrameOutcome::Written(render_scene(&d, opts, reporter)?)
        };
        return Ok(JobReport {
            frames: vec![(None, outcome)],
        });
    };
    let mut desc = desc.clone();
    fix_sequence_bounds(&mut desc)?;
    // Inputs missing for every frame: most likely a wrong pattern or
    // frame range, which one message says better than one per frame.
    let inputs = sequence_inputs(&desc)?;
    for i in &inputs {
        if !frames
            .iter()
            .any(|&f| i.path(f).is_some_and(|p| p.is_file()))
        {
            let found = i.pattern.existing_frames();
            let hint = if found.is_empty() {
                "no frame of it exists".to_string()
            } else {
                format!("its files are frames {}", format_frames(&found))
            };
            let offset = if i.offset != 0 {
                format!(" (frame_offset {})", i.offset)
            } else {
                String::new()
            };
            let which = match frames.as_slice() {
                [f] => format!("frame {f}{offset}"),
                _ => format!("frames {}{offset}", format_frames(&frames)),
            };
            return Err(Error::Argument(format!(
                "the sequence '{}' has no file for {which}; {hint}",
                i.pattern.expand(None, None).display(),
            )));
        }
    }
    let mut report = JobReport::default();
    for (i, &frame) in frames.iter().enumerate() {
        let t0 = Instant::now();
        reporter.frame_started(frame, i, frames.len());
        let outcome = match render_frame(&desc, frame, job, opts, reporter, &inputs) {
            Ok(o) => o,
            Err(e) if e.is_interrupt() => return Err(e),
            Err(e) => FrameOutcome::Failed(e),
        };
        reporter.frame_done(frame, &outcome, t0.elapsed().as_secs_f64());
        report.frames.push((Some(frame), outcome));
    }
    Ok(report)
}

fn render_frame(
    desc: &SceneDesc,
    frame: u32,
    job: &FrameJob,
    opts: &RenderOptions,
    reporter: &dyn Reporter,
    inputs: &[Input],
) -> Result<FrameOutcome> {
    for i in inputs {
        let Some(path) = i.path(frame) else {
            return Err(Error::file(
                &i.pattern.expand(None, None),
                format!(
                    "frame {frame} with frame_offset {} is before frame 0",
                    i.offset
                ),
            ));
        };
        if !path.is_file() {
            return Err(Error::file(
                &path,
                format!("frame {frame} of the sequence does not exist"),
            ));
        }
    }
    let d = scene_at(desc, Some(frame), opts.tile.map(|t| t.0))?;
    if job.skip_existing && crate::render::resume::is_finished(&d.render.output) {
        return Ok(FrameOutcome::Skipped(d.render.output.clone()));
    }
    let mut o = opts.clone();
    o.attributes
        .push(("vdbphoton/frame".into(), frame.to_string()));
    Ok(FrameOutcome::Written(render_scene(&d, &o, reporter)?))
}
