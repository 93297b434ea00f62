//! What a command line or a job script changes of a scene before it
//! renders, applied and checked in one place (the CLI and the fuzz targets
//! share it), so that an override is held to the scene file's own rules.

use crate::error::{Error, Result};
use crate::scene::SceneDesc;
use std::path::{Path, PathBuf};

/// Changes to a scene's `[render]`; `None` and `false` leave the scene's
/// own value. Paths are taken as given (the command line's are relative to
/// the working directory, not to the scene file).
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// The EXR. A preview the scene asks for follows it (same name, `.png`)
    /// unless `preview` is given, instead of overwriting the scene's own.
    pub output: Option<PathBuf>,
    pub preview: Option<PathBuf>,
    /// Write no preview, whatever the scene says.
    pub no_preview: bool,
    pub spp: Option<u32>,
    pub seed: Option<u64>,
    pub max_bounces: Option<u32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub exposure: Option<f32>,
    /// An integrator's name (`auto` or one of `crate::integrator::REGISTRY`).
    pub integrator: Option<String>,
    /// Write the AOV layers (on when either asks).
    pub aovs: bool,
    /// Denoise (on when either asks).
    pub denoise: bool,
    /// The denoiser's quality.
    pub denoise_quality: Option<crate::scene::DenoiseQuality>,
    /// Resume from a killed render's state (on when either asks).
    pub resume: bool,
}

impl Overrides {
    /// Applies the changes to `desc` and checks the scene again (its own
    /// rules and its integrator's settings); errors name `scene`.
    pub fn apply(&self, desc: &mut SceneDesc, scene: &Path) -> Result<()> {
        let r = &mut desc.render;
        if let Some(o) = &self.output {
            if self.preview.is_none() && r.preview.is_some() {
                r.preview = Some(o.with_extension("png"));
            }
            r.output = o.clone();
        }
        if let Some(p) = &self.preview {
            r.preview = Some(p.clone());
        }
        if self.no_preview {
            r.preview = None;
        }
        if let Some(v) = self.spp {
            r.spp = v;
        }
        if let Some(v) = self.seed {
            r.seed = v;
        }
        if let Some(v) = self.max_bounces {
            r.max_bounces = v;
        }
        if let Some(v) = self.width {
            r.width = v;
        }
        if let Some(v) = self.height {
            r.height = v;
        }
        if let Some(v) = self.exposure {
            r.exposure = v;
        }
        if let Some(i) = &self.integrator {
            r.integrator = i.clone();
        }
        r.aovs |= self.aovs;
        r.denoise |= self.denoise;
        r.resume |= self.resume;
        if let Some(q) = self.denoise_quality {
            r.denoise_quality = q;
        }
        desc.validate()
            .map_err(|e| e.to_string())
            .and_then(|()| crate::integrator::check_settings(desc).map_err(|e| e.to_string()))
            .map_err(|e| {
                Error::Argument(format!(
                    "{}: after the command-line options: {e}",
                    scene.display()
                ))
            })
    }
}
