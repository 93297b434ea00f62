//! The film: per-pixel sums of camera samples and their counts, over the
//! passes of a render. Sums rather than means so that passes accumulate
//! (each pass adds its samples), a render stopped by a time budget is as
//! valid as one stopped by a sample count, and renders of the same pixels
//! with different seeds merge by adding (weighted by their counts).
//!
//! A film covers a [`Region`] of the full image (all of it, or a tile);
//! pixels are addressed in full-image coordinates, row-major from the top.

use crate::image::{Image, ImageError};
use crate::Rgb;
use glam::{DVec3, Vec4};

/// What one camera sample returns.
#[derive(Debug, Clone, Copy, Default)]
pub struct SampleResult {
    /// Radiance along the camera ray.
    pub l: Rgb,
    /// Light that scattered once in the media (lights and environment).
    pub direct: Rgb,
    /// Light that scattered more than once.
    pub indirect: Rgb,
    /// Emission of the media (at any depth).
    pub emission: Rgb,
    /// Transmittance along the camera ray (mean over channels; alpha is 1
    /// minus it).
    pub transmittance: f32,
    /// The denoising albedo along the camera ray, for the samples that
    /// carry the denoiser's guide (`crate::integrator::guide`).
    pub albedo: Option<Rgb>,
    /// What a camera ray that met a shadow catcher gives the Shadow
    /// Catcher pass (`crate::integrator::catcher`), weighted by the
    /// transmittance up to the catcher.
    pub catcher: Option<CatcherSample>,
    /// The light of paths whose first scattering is on a surface, by the
    /// lobe that scattered it (Blender's Diffuse and Glossy passes); the
    /// fields above then hold none of it but the emission the camera sees.
    pub surface: SurfaceAovs,
}

/// Blender's Diffuse Direct, Diffuse Indirect, Glossy Direct and Glossy
/// Indirect passes, colour included (Cycles' pass times its Diffuse or
/// Glossy Color pass). A path counts in them when its first scattering is
/// on a surface: direct, the light that reaches that point from the lights,
/// the world, emitting surfaces and glowing media (its light sample and
/// what its BSDF-sampled ray finds before it scatters again); indirect,
/// what comes after; diffuse or glossy by the lobe of the BSDF (its light
/// sample split by lobe, the rest by the lobe its direction came from).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SurfaceAovs {
    pub diffuse_direct: Rgb,
    pub diffuse_indirect: Rgb,
    pub glossy_direct: Rgb,
    pub glossy_indirect: Rgb,
}

impl SurfaceAovs {
    /// Their layer names, as Blender's passes.
    pub const LAYERS: [&'static str; 4] = [
        "diffuse_direct",
        "diffuse_indirect",
        "glossy_direct",
        "glossy_indirect",
    ];

    fn get(&self) -> [Rgb; 4] {
        [
            self.diffuse_direct,
            self.diffuse_indirect,
            self.glossy_direct,
            self.glossy_indirect,
        ]
    }

    /// Each pass times `w` (per channel).
    pub fn times(&self, w: Rgb) -> SurfaceAovs {
        SurfaceAovs {
            diffuse_direct: self.diffuse_direct * w,
            diffuse_indirect: self.diffuse_indirect * w,
            glossy_direct: self.glossy_direct * w,
            glossy_indirect: self.glossy_indirect * w,
        }
    }

    /// The four passes together.
    pub fn total(&self) -> Rgb {
        self.diffuse_direct + self.diffuse_indirect + self.glossy_direct + self.glossy_indirect
    }

    /// Adds `other`'s passes.
    pub fn add(&mut self, other: &SurfaceAovs) {
        self.diffuse_direct += other.diffuse_direct;
        self.diffuse_indirect += other.diffuse_indirect;
        self.glossy_direct += other.glossy_direct;
        self.glossy_indirect += other.glossy_indirect;
    }

    /// Adds `l` to the pass of `glossy`'s lobe, direct or not.
    #[inline]
    pub fn add_to(&mut self, glossy: bool, direct: bool, l: Rgb) {
        match (glossy, direct) {
            (false, true) => self.diffuse_direct += l,
            (false, false) => self.diffuse_indirect += l,
            (true, true) => self.glossy_direct += l,
            (true, false) => self.glossy_indirect += l,
        }
    }
}

/// The light a shadow catcher receives with everything in the scene
/// (`shadowed`) and with only the lights and the world (`unshadowed`):
/// their ratio, summed over a pixel's samples, is Cycles' Shadow Catcher
/// pass (`film_calculate_shadow_catcher`, `kernel/film/read.h`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CatcherSample {
    pub shadowed: Rgb,
    pub unshadowed: Rgb,
}

impl CatcherSample {
    /// Both estimates times `w`.
    pub fn scaled(self, w: f32) -> Self {
        Self {
            shadowed: self.shadowed * w,
            unshadowed: self.unshadowed * w,
        }
    }
}

/// Sums of one pixel's shadow-catcher estimates, and how many of its
/// samples saw a catcher.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct CatcherSums {
    shadowed: Rgb,
    unshadowed: Rgb,
    hits: u32,
}

/// The name of the Shadow Catcher pass's layer in the EXR.
pub const SHADOW_CATCHER_LAYER: &str = "shadow_catcher";

/// A rectangle of pixels `[x0, x1) × [y0, y1)` in a `width` x `height`
/// image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Region {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Region {
    /// The whole `width` x `height` image.
    pub fn full(width: u32, height: u32) -> Self {
        Self {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    pub fn pixels(&self) -> usize {
        self.width() as usize * self.height() as usize
    }
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }
    /// Whether the two regions share a pixel.
    pub fn overlaps(&self, o: &Region) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }

    /// The grid `--tile I/N` cuts a `width` x `height` image into: `cols` x
    /// `rows` = `n` tiles as close to square as the factors of `n` allow
    /// (ties: more columns).
    pub fn tile_grid(n: u32, width: u32, height: u32) -> (u32, u32) {
        let mut best = (n, 1);
        let mut best_score = f64::INFINITY;
        for cols in (1..=n).rev() {
            if !n.is_multiple_of(cols) {
                continue;
            }
            let rows = n / cols;
            let aspect = (width as f64 / cols as f64) / (height as f64 / rows as f64);
            let score = aspect.ln().abs();
            if score < best_score - 1e-12 {
                best = (cols, rows);
                best_score = score;
            }
        }
        best
    }

    /// Tile `i` of `n` of a `width` x `height` image (`--tile I/N`):
    /// row-major from the top-left in the grid of [`Region::tile_grid`],
    /// edges at `floor(width · col / cols)`, so the tiles cover the image
    /// without overlap. `None` when `i >= n`, `n` is 0 or a tile would be
    /// empty.
    pub fn tile(i: u32, n: u32, width: u32, height: u32) -> Option<Region> {
        if n == 0 || i >= n {
            return None;
        }
        let (cols, rows) = Self::tile_grid(n, width, height);
        let (c, r) = (i % cols, i / cols);
        let edge = |k: u32, of: u32, size: u32| (size as u64 * k as u64 / of as u64) as u32;
        let t = Region {
            x0: edge(c, cols, width),
            x1: edge(c + 1, cols, width),
            y0: edge(r, rows, height),
            y1: edge(r + 1, rows, height),
        };
        (t.pixels() > 0).then_some(t)
    }

    /// Reads `X0,Y0,X1,Y1` (`--region`), checked against a `width` x
    /// `height` image.
    pub fn parse(s: &str, width: u32, height: u32) -> Result<Region, String> {
        let v: Vec<u32> = s
            .split(',')
            .map(|t| t.trim().parse().ok())
            .collect::<Option<_>>()
            .filter(|v: &Vec<u32>| v.len() == 4)
            .ok_or_else(|| {
                format!(
                    "--region '{s}': expected four pixel numbers X0,Y0,X1,Y1 (e.g. 0,0,160,120)"
                )
            })?;
        let r = Region {
            x0: v[0],
            y0: v[1],
            x1: v[2],
            y1: v[3],
        };
        if r.x0 >= r.x1 || r.y0 >= r.y1 {
            return Err(format!(
                "--region '{s}': the region is empty (X0 < X1 and Y0 < Y1 are needed)"
            ));
        }
        if r.x1 > width || r.y1 > height {
            return Err(format!(
                "--region '{s}' reaches outside the {width} x {height} image"
            ));
        }
        Ok(r)
    }
}

impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

/// Sums of one pixel's AOVs: light scattered once, more than once, emission.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct AovSums {
    direct: Rgb,
    indirect: Rgb,
    emission: Rgb,
}

/// Sums of one pixel's denoising albedo, over the samples that carried it
/// (the first few: `crate::integrator::guide::GUIDE_SAMPLES`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct GuideSums {
    albedo: Rgb,
    samples: u32,
}

/// Per-pixel sums over the camera samples of a render.
#[derive(Debug, Clone, PartialEq)]
pub struct Film {
    /// The full image this film is part of.
    pub width: u32,
    pub height: u32,
    pub region: Region,
    /// Radiance sums (f64: thousands of passes add without losing digits).
    l: Vec<DVec3>,
    /// Sums of the camera ray's transmittance (mean over channels).
    transmittance: Vec<f64>,
    /// AOV sums, when they are kept.
    aovs: Option<Vec<AovSums>>,
    /// Sums of the denoising albedo, when the render is denoised.
    guides: Option<Vec<GuideSums>>,
    /// Radiance sums of every other sample (the 2nd, 4th, ...), when the
    /// render is denoised: one half of the samples, independent of the
    /// other half (a pass has one sample a pixel, so the halves take
    /// alternate passes, photon maps included); the denoiser measures its
    /// own error with them (`crate::denoise::blend`).
    half: Option<Vec<Rgb>>,
    /// Shadow-catcher sums, when the scene has a catcher.
    catcher: Option<Vec<CatcherSums>>,
    /// Surface AOV sums, when AOVs are kept and the scene has surfaces.
    surface: Option<Vec<SurfaceAovs>>,
    /// Samples per pixel so far.
    samples: Vec<u32>,
}

impl Film {
    /// Bytes per pixel the denoising albedo and half sums add at most
    /// ([`Self::with_guides`], [`Self::with_half`]).
    pub const DENOISE_BYTES: usize = std::mem::size_of::<GuideSums>() + std::mem::size_of::<Rgb>();
    /// Bytes per pixel the shadow catcher's sums add
    /// ([`Self::with_catcher`]), and its layer in the image.
    pub const CATCHER_BYTES: usize = std::mem::size_of::<CatcherSums>() + 2 * 4 * 3;
    /// Bytes per pixel the surface AOVs add ([`Self::with_surface_aovs`]),
    /// and their 12 channels in the image (counted twice, as the memory
    /// check counts the image's other layers: the image and its copy
    /// written out).
    pub const SURFACE_AOV_BYTES: usize = std::mem::size_of::<SurfaceAovs>() + 2 * 4 * 12;

    /// An empty film over `region` of a `width` x `height` image, with AOV
    /// sums when `aovs`.
    pub fn new(width: u32, height: u32, region: Region, aovs: bool) -> Self {
        let n = region.pixels();
        Self {
            width,
            height,
            region,
            l: vec![DVec3::ZERO; n],
            transmittance: vec![0.0; n],
            aovs: aovs.then(|| vec![AovSums::default(); n]),
            guides: None,
            half: None,
            catcher: None,
            surface: None,
            samples: vec![0; n],
        }
    }

    /// The film also keeps the surface AOVs ([`SurfaceAovs`]), written as
    /// their layers; only with AOVs.
    pub fn with_surface_aovs(self) -> Self {
        let n = self.samples.len();
        Self {
            surface: self.aovs.is_some().then(|| vec![SurfaceAovs::default(); n]),
            ..self
        }
    }

    /// The film also keeps the shadow catcher's sums, written as the layer
    /// [`SHADOW_CATCHER_LAYER`] (Cycles' Shadow Catcher pass).
    pub fn with_catcher(self) -> Self {
        let n = self.samples.len();
        Self {
            catcher: Some(vec![CatcherSums::default(); n]),
            ..self
        }
    }

    /// Whether the film keeps the shadow catcher's sums.
    pub fn has_catcher(&self) -> bool {
        self.catcher.is_some()
    }

    /// The film also keeps the denoising albedo of the samples that carry
    /// it ([`SampleResult::albedo`]), written as the layer `albedo`.
    pub fn with_guides(self) -> Self {
        let n = self.samples.len();
        Self {
            guides: Some(vec![GuideSums::default(); n]),
            ..self
        }
    }

    /// The film also keeps the radiance of every other sample, written as
    /// the layer `half` (their mean) once every pixel has two samples:
    /// the denoiser then measures its own error (`crate::denoise::blend`).
    pub fn with_half(self) -> Self {
        let n = self.samples.len();
        Self {
            half: Some(vec![Rgb::ZERO; n]),
            ..self
        }
    }

    /// Whether the film keeps the half sums.
    pub fn has_half(&self) -> bool {
        self.half.is_some()
    }

    /// Whether the film keeps the denoising albedo.
    pub fn has_guides(&self) -> bool {
        self.guides.is_some()
    }

    /// Bytes a film of `pixels` pixels takes (with the AOVs when `aovs`),
    /// for memory checks before a render; a denoised render's film takes
    /// [`Self::DENOISE_BYTES`] a pixel more.
    pub fn bytes_for(pixels: usize, aovs: bool) -> usize {
        pixels
            * (std::mem::size_of::<DVec3>()
                + 8
                + 4
                + if aovs {
                    std::mem::size_of::<AovSums>()
                } else {
                    0
                })
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> usize {
        debug_assert!(self.region.contains(x, y));
        (y - self.region.y0) as usize * self.region.width() as usize + (x - self.region.x0) as usize
    }

    /// Adds one camera sample of pixel (x, y) (full-image coordinates). A
    /// sample whose radiance is not finite counts with zero radiance, so
    /// one bad path cannot spoil a pixel.
    #[inline]
    pub fn add(&mut self, x: u32, y: u32, s: &SampleResult) {
        let i = self.index(x, y);
        let finite = s.l.is_finite();
        if finite {
            self.l[i] += s.l.as_dvec3();
            if let (Some(h), 1) = (&mut self.half, self.samples[i] % 2) {
                h[i] += s.l;
            }
        }
        self.transmittance[i] += s.transmittance as f64;
        self.samples[i] += 1;
        if let (Some(a), true) = (&mut self.aovs, finite) {
            a[i].direct += s.direct;
            a[i].indirect += s.indirect;
            a[i].emission += s.emission;
        }
        if let (Some(a), Some(albedo)) = (&mut self.guides, s.albedo) {
            if albedo.is_finite() {
                a[i].albedo += albedo;
                a[i].samples += 1;
            }
        }
        if let (Some(a), true) = (&mut self.surface, finite) {
            a[i].add(&s.surface);
        }
        if let (Some(a), Some(c)) = (&mut self.catcher, s.catcher) {
            a[i].hits += 1;
            if c.shadowed.is_finite() && c.unshadowed.is_finite() {
                a[i].shadowed += c.shadowed;
                a[i].unshadowed += c.unshadowed;
            }
        }
    }

    /// Adds every sum and count of `other`, a film of the same region.
    pub fn merge(&mut self, other: &Film) -> Result<(), String> {
        if other.region != self.region || (other.width, other.height) != (self.width, self.height) {
            return Err("films of different regions cannot be merged".into());
        }
        for i in 0..self.l.len() {
            self.l[i] += other.l[i];
            self.transmittance[i] += other.transmittance[i];
            self.samples[i] += other.samples[i];
        }
        if let (Some(a), Some(b)) = (&mut self.aovs, &other.aovs) {
            for (x, y) in a.iter_mut().zip(b) {
                x.direct += y.direct;
                x.indirect += y.indirect;
                x.emission += y.emission;
            }
        }
        if let (Some(a), Some(b)) = (&mut self.guides, &other.guides) {
            for (x, y) in a.iter_mut().zip(b) {
                x.albedo += y.albedo;
                x.samples += y.samples;
            }
        }
        if let (Some(a), Some(b)) = (&mut self.surface, &other.surface) {
            for (x, y) in a.iter_mut().zip(b) {
                x.add(y);
            }
        }
        if let (Some(a), Some(b)) = (&mut self.half, &other.half) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += *y;
            }
        }
        if let (Some(a), Some(b)) = (&mut self.catcher, &other.catcher) {
            for (x, y) in a.iter_mut().zip(b) {
                x.shadowed += y.shadowed;
                x.unshadowed += y.unshadowed;
                x.hits += y.hits;
            }
        }
        Ok(())
    }

    /// Whether the film keeps the AOV sums.
    pub fn has_aovs(&self) -> bool {
        self.aovs.is_some()
    }

    /// Bytes [`Self::write_sums`] writes.
    pub fn sums_bytes(&self) -> u64 {
        let n = self.samples.len() as u64;
        n * (3 * 8 + 8 + 4)
            + self.aovs.as_ref().map_or(0, |_| n * 9 * 4)
            + self.guides.as_ref().map_or(0, |_| n * 4 * 4)
            + self.half.as_ref().map_or(0, |_| n * 3 * 4)
            + self.catcher.as_ref().map_or(0, |_| n * 7 * 4)
    }

    /// Writes every sum and count, little-endian, bit for bit (a resumed
    /// render's film, `crate::render::resume`): radiance, transmittance,
    /// counts, then the AOVs, the albedo and the half sums when kept.
    pub fn write_sums(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        fn put<T, const N: usize>(
            w: &mut impl std::io::Write,
            v: &[T],
            bytes: impl Fn(&T, &mut Vec<u8>),
        ) -> std::io::Result<()> {
            let mut buf = Vec::with_capacity(N * 4096);
            for chunk in v.chunks(4096) {
                buf.clear();
                for x in chunk {
                    bytes(x, &mut buf);
                }
                w.write_all(&buf)?;
            }
            Ok(())
        }
        let f32s = |b: &mut Vec<u8>, c: Rgb| {
            for x in c.to_array() {
                b.extend_from_slice(&x.to_le_bytes());
            }
        };
        put::<_, 24>(w, &self.l, |x, b| {
            for c in x.to_array() {
                b.extend_from_slice(&c.to_le_bytes());
            }
        })?;
        put::<_, 8>(w, &self.transmittance, |x, b| {
            b.extend_from_slice(&x.to_le_bytes())
        })?;
        put::<_, 4>(w, &self.samples, |x, b| {
            b.extend_from_slice(&x.to_le_bytes())
        })?;
        if let Some(a) = &self.aovs {
            put::<_, 36>(w, a, |s, b| {
                f32s(b, s.direct);
                f32s(b, s.indirect);
                f32s(b, s.emission);
            })?;
        }
        if let Some(a) = &self.guides {
            put::<_, 16>(w, a, |g, b| {
                f32s(b, g.albedo);
                b.extend_from_slice(&g.samples.to_le_bytes());
            })?;
        }
        if let Some(a) = &self.half {
            put::<_, 12>(w, a, |c, b| f32s(b, *c))?;
        }
        if let Some(a) = &self.catcher {
            put::<_, 28>(w, a, |c, b| {
                f32s(b, c.shadowed);
                f32s(b, c.unshadowed);
                b.extend_from_slice(&c.hits.to_le_bytes());
            })?;
        }
        if let Some(a) = &self.surface {
            put::<_, 48>(w, a, |c, b| {
                for x in c.get() {
                    f32s(b, x);
                }
            })?;
        }
        Ok(())
    }

    /// Reads what [`Self::write_sums`] wrote of a film of this layout
    /// (region, AOVs, guides, half) from `r` into this film, replacing its sums
    /// (a chunk at a time: no second copy of the film in memory).
    pub fn read_sums(&mut self, r: &mut impl std::io::Read) -> Result<(), String> {
        fn get<T, const N: usize>(
            r: &mut impl std::io::Read,
            v: &mut [T],
            from: impl Fn(&[u8]) -> T,
        ) -> Result<(), String> {
            let mut buf = vec![0u8; N * 4096];
            for chunk in v.chunks_mut(4096) {
                let b = &mut buf[..N * chunk.len()];
                r.read_exact(b)
                    .map_err(|e| format!("the film's sums end early: {e}"))?;
                for (x, bytes) in chunk.iter_mut().zip(b.chunks_exact(N)) {
                    *x = from(bytes);
                }
            }
            Ok(())
        }
        let f64_at =
            |s: &[u8], i: usize| f64::from_le_bytes(s[8 * i..8 * i + 8].try_into().unwrap());
        let f32_at =
            |s: &[u8], i: usize| f32::from_le_bytes(s[4 * i..4 * i + 4].try_into().unwrap());
        let rgb_at =
            |s: &[u8], i: usize| Rgb::new(f32_at(s, i), f32_at(s, i + 1), f32_at(s, i + 2));
        get::<_, 24>(r, &mut self.l, |s| {
            DVec3::new(f64_at(s, 0), f64_at(s, 1), f64_at(s, 2))
        })?;
        get::<_, 8>(r, &mut self.transmittance, |s| f64_at(s, 0))?;
        get::<_, 4>(r, &mut self.samples, |s| {
            u32::from_le_bytes(s.try_into().unwrap())
        })?;
        if let Some(a) = &mut self.aovs {
            get::<_, 36>(r, a, |s| AovSums {
                direct: rgb_at(s, 0),
                indirect: rgb_at(s, 3),
                emission: rgb_at(s, 6),
            })?;
        }
        if let Some(a) = &mut self.guides {
            get::<_, 16>(r, a, |s| GuideSums {
                albedo: rgb_at(s, 0),
                samples: u32::from_le_bytes(s[12..16].try_into().unwrap()),
            })?;
        }
        if let Some(a) = &mut self.half {
            get::<_, 12>(r, a, |s| rgb_at(s, 0))?;
        }
        if let Some(a) = &mut self.catcher {
            get::<_, 28>(r, a, |s| CatcherSums {
                shadowed: rgb_at(s, 0),
                unshadowed: rgb_at(s, 3),
                hits: u32::from_le_bytes(s[24..28].try_into().unwrap()),
            })?;
        }
        if let Some(a) = &mut self.surface {
            get::<_, 48>(r, a, |s| SurfaceAovs {
                diffuse_direct: rgb_at(s, 0),
                diffuse_indirect: rgb_at(s, 3),
                glossy_direct: rgb_at(s, 6),
                glossy_indirect: rgb_at(s, 9),
            })?;
        }
        Ok(())
    }

    /// Samples of pixel (x, y).
    pub fn samples(&self, x: u32, y: u32) -> u32 {
        self.samples[self.index(x, y)]
    }

    /// The fewest samples any pixel has.
    pub fn min_samples(&self) -> u32 {
        self.samples.iter().copied().min().unwrap_or(0)
    }

    fn inv(&self, i: usize) -> f64 {
        if self.samples[i] == 0 {
            0.0
        } else {
            1.0 / self.samples[i] as f64
        }
    }

    /// Mean radiance per pixel of the region, row-major.
    pub fn mean_rgb(&self) -> Vec<Rgb> {
        (0..self.l.len())
            .map(|i| (self.l[i] * self.inv(i)).as_vec3())
            .collect()
    }

    /// Mean transmittance of the camera rays per pixel of the region.
    pub fn mean_transmittance(&self) -> Vec<f32> {
        (0..self.l.len())
            .map(|i| {
                if self.samples[i] == 0 {
                    1.0
                } else {
                    (self.transmittance[i] * self.inv(i)) as f32
                }
            })
            .collect()
    }

    /// The Shadow Catcher pass of pixel `i` of the region (Cycles'
    /// `film_calculate_shadow_catcher`): per channel the shadowed over the
    /// unshadowed sum (1 where that is 0), mixed with 1 by the share of
    /// samples that did not see a catcher.
    fn catcher_pass(&self, i: usize, c: &CatcherSums) -> Rgb {
        let seen = c.hits as f32 * self.inv(i) as f32;
        let ratio = Rgb::select(
            c.unshadowed.cmpgt(Rgb::ZERO),
            c.shadowed / c.unshadowed.max(Rgb::splat(f32::MIN_POSITIVE)),
            Rgb::ONE,
        );
        Rgb::splat(1.0 - seen) + ratio * seen
    }

    /// The means as an image of the region, placed in the whole image (its
    /// data window): RGBA (alpha = 1 − the transmittance along the camera
    /// ray) and, when kept, the AOV layers `direct`, `indirect`, `emission`
    /// and `transmittance`, the denoiser's `albedo` and `half`, and the
    /// Shadow Catcher pass ([`SHADOW_CATCHER_LAYER`]).
    pub fn to_image(&self) -> Result<Image, ImageError> {
        let (w, h) = (self.region.width() as usize, self.region.height() as usize);
        let tr = self.mean_transmittance();
        let rgba: Vec<Vec4> = self
            .mean_rgb()
            .iter()
            .zip(&tr)
            .map(|(c, t)| c.extend((1.0 - t).clamp(0.0, 1.0)))
            .collect();
        let mut image = Image::from_pixels(w, h, rgba)?;
        if let Some(a) = &self.aovs {
            type Pick = fn(&AovSums) -> Rgb;
            let layers: [(&str, Pick); 3] = [
                ("direct", |s| s.direct),
                ("indirect", |s| s.indirect),
                ("emission", |s| s.emission),
            ];
            let inv: Vec<f32> = (0..a.len()).map(|i| self.inv(i) as f32).collect();
            for (name, pick) in layers {
                let layer = image.add_rgb_layer(name)?;
                for (i, s) in a.iter().enumerate() {
                    layer.set(i % w, i / w, &(pick(s) * inv[i]).to_array());
                }
            }
            let layer = image.add_layer("transmittance", &["Y"])?;
            for (i, t) in tr.iter().enumerate() {
                layer.set(i % w, i / w, &[*t]);
            }
            if let Some(sa) = &self.surface {
                for (k, name) in SurfaceAovs::LAYERS.iter().enumerate() {
                    let layer = image.add_rgb_layer(name)?;
                    for (i, s) in sa.iter().enumerate() {
                        layer.set(i % w, i / w, &(s.get()[k] * inv[i]).to_array());
                    }
                }
            }
        }
        if let Some(a) = &self.guides {
            let layer = image.add_rgb_layer(crate::denoise::ALBEDO_LAYER)?;
            for (i, g) in a.iter().enumerate() {
                let inv = 1.0 / g.samples.max(1) as f32;
                layer.set(i % w, i / w, &(g.albedo * inv).to_array());
            }
        }
        // The half's mean needs a sample in it everywhere.
        if let (Some(h), true) = (&self.half, self.min_samples() >= 2) {
            let layer = image.add_rgb_layer(crate::denoise::HALF_LAYER)?;
            for (i, s) in h.iter().enumerate() {
                let n = self.samples[i] / 2;
                layer.set(i % w, i / w, &(*s / n as f32).to_array());
            }
        }
        if let Some(a) = &self.catcher {
            let layer = image.add_rgb_layer(SHADOW_CATCHER_LAYER)?;
            for (i, c) in a.iter().enumerate() {
                layer.set(i % w, i / w, &self.catcher_pass(i, c).to_array());
            }
        }
        image.set_window(
            (self.region.x0 as usize, self.region.y0 as usize),
            (self.width as usize, self.height as usize),
        )?;
        Ok(image)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `half` layer is the mean of every other sample (the 2nd, 4th,
    /// ...: alternate passes), and it is written only once every pixel has
    /// two samples, so that it is a mean everywhere.
    #[test]
    fn the_half_layer_is_the_mean_of_every_other_sample() {
        let mut film = Film::new(2, 1, Region::full(2, 1), false).with_half();
        let sample = |v: f32| SampleResult {
            l: Rgb::splat(v),
            ..SampleResult::default()
        };
        for v in [1.0, 2.0, 3.0, 4.0, 5.0] {
            film.add(0, 0, &sample(v));
        }
        film.add(1, 0, &sample(7.0));
        let half = crate::denoise::HALF_LAYER;
        assert!(film.to_image().unwrap().layer(half).is_none());
        film.add(1, 0, &sample(9.0));
        let image = film.to_image().unwrap();
        let layer = image.layer(half).unwrap();
        assert_eq!(layer.get(0, 0), &[3.0, 3.0, 3.0]);
        assert_eq!(layer.get(1, 0), &[9.0, 9.0, 9.0]);
        assert_eq!(image.get(0, 0).x, 3.0);
        resumes_bit_for_bit(
            &film,
            Film::new(2, 1, Region::full(2, 1), false).with_half(),
        );
    }

    /// `film`'s sums, written as the resume state and read back into
    /// `empty` (a film of its layout), are `film` bit for bit.
    fn resumes_bit_for_bit(film: &Film, mut empty: Film) {
        let mut bytes = Vec::new();
        film.write_sums(&mut bytes).unwrap();
        assert_eq!(bytes.len() as u64, film.sums_bytes());
        empty.read_sums(&mut bytes.as_slice()).unwrap();
        assert_eq!(&empty, film);
    }

    /// The albedo layer is the mean over the samples that carried the
    /// guide (the first few of a pixel), not over all of its samples;
    /// merged films add their guide counts.
    #[test]
    fn the_albedo_is_the_mean_of_the_samples_that_carry_it() {
        let mut film = Film::new(1, 1, Region::full(1, 1), false).with_guides();
        let guided = |a: f32| SampleResult {
            albedo: Some(Rgb::splat(a)),
            ..SampleResult::default()
        };
        film.add(0, 0, &guided(0.2));
        film.add(0, 0, &guided(0.6));
        film.add(0, 0, &SampleResult::default());
        let mut other = Film::new(1, 1, Region::full(1, 1), false).with_guides();
        other.add(0, 0, &guided(0.7));
        film.merge(&other).unwrap();
        let image = film.to_image().unwrap();
        let albedo = image.layer(crate::denoise::ALBEDO_LAYER).unwrap();
        assert_eq!(albedo.get(0, 0), &[0.5, 0.5, 0.5]);
        resumes_bit_for_bit(
            &film,
            Film::new(1, 1, Region::full(1, 1), false).with_guides(),
        );
    }
}
