//! Resuming a killed render where its last checkpoint left it.
//!
//! With `--checkpoint`, every checkpoint also writes the render's state
//! beside the EXR (`frame.exr.vdbstate`): the film's sums and counts bit
//! for bit, the passes done, the time spent, and what the integrator
//! carries from pass to pass ([`crate::integrator::Integrator::state`]).
//! Every random number of pass `k` comes from (seed, pass) or (seed,
//! pixel, sample) streams, so a render resumed after `k` passes computes
//! exactly what the uninterrupted one computed next: the same pixels, bit
//! for bit, whenever it was stopped.
//!
//! A state is resumed only by the render it belongs to: the same build of
//! vdbphoton (a hash of the executable: another build may round
//! differently), the same scene (its description and the size and time of
//! its input files), seed, image size, region or tile, integrator and film
//! layout. Anything else, or a file that is damaged (a checksum over the
//! whole file), is refused with the reason and the render starts afresh;
//! the old state and EXR stay until the new render's first checkpoint
//! replaces them. A state is written before its EXR and removed after the
//! finished render's EXR, so an EXR with a state beside it is a checkpoint
//! (`--skip-existing` renders it again) and one without is finished.
//!
//! Two renders of one output would overwrite each other's state: a render
//! that checkpoints or resumes holds a lock on `frame.exr.lock` (`flock`,
//! which the kernel releases when the process dies, so a killed render
//! leaves no stale lock).

use crate::error::{Error, Result};
use crate::film::{Film, Region};
use crate::integrator::PassState;
use crate::scene::{EnvironmentDesc, SceneDesc};
use std::fs::File;
use std::hash::Hasher;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

const MAGIC: &str = "vdbphoton render state 1";

/// Bytes hashed at a time, so that a writer and a reader that cut the
/// stream differently agree.
const HASH_CHUNK: usize = 1 << 20;

/// `path` with `suffix` added to its file name.
fn beside(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Where the state of a render writing `output` is kept.
pub fn state_path(output: &Path) -> PathBuf {
    beside(output, ".vdbstate")
}

/// The lock of a render writing `output`.
pub fn lock_path(output: &Path) -> PathBuf {
    beside(output, ".lock")
}

/// Whether `output` holds a finished render: it exists and no state beside
/// it says it is a checkpoint (`--skip-existing`).
pub fn is_finished(output: &Path) -> bool {
    output.is_file() && !state_path(output).exists()
}

/// Ends the state of a finished render: its EXR `output` synced to disk
/// (with its folder, so that the rename is too), then the state at
/// `state` removed, so that a power cut cannot leave an old or empty EXR
/// without the state that says it is unfinished.
pub fn finish(output: &Path, state: &Path) -> std::result::Result<(), String> {
    let sync = |p: &Path| File::open(p).and_then(|f| f.sync_all());
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    sync(output).and_then(|()| sync(dir)).map_err(|e| {
        format!(
            "cannot sync '{}' to disk ({e}); its resume state '{}' is kept",
            output.display(),
            state.display()
        )
    })?;
    match std::fs::remove_file(state) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(format!(
            "cannot remove the finished render's state '{}': {e}",
            state.display()
        )),
        _ => Ok(()),
    }
}

/// A hash of a byte stream, fed in fixed chunks.
struct ChunkHash {
    hasher: std::collections::hash_map::DefaultHasher,
    buf: Vec<u8>,
}

impl ChunkHash {
    fn new() -> Self {
        Self {
            hasher: Default::default(),
            buf: Vec::with_capacity(HASH_CHUNK),
        }
    }
    fn update(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let n = (HASH_CHUNK - self.buf.len()).min(bytes.len());
            self.buf.extend_from_slice(&bytes[..n]);
            bytes = &bytes[n..];
            if self.buf.len() == HASH_CHUNK {
                self.hasher.write(&self.buf);
                self.buf.clear();
            }
        }
    }
    fn finish(mut self) -> u64 {
        self.hasher.write(&self.buf);
        self.hasher.write_usize(0xfeed);
        self.hasher.finish()
    }
}

/// A writer that hashes what passes through it.
struct Hashing<W: Write> {
    inner: W,
    hash: ChunkHash,
}

impl<W: Write> Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// This build of vdbphoton: its version and a hash of its executable.
pub fn binary_fingerprint() -> &'static str {
    static FP: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    FP.get_or_init(|| {
        let exe = std::env::current_exe()
            .ok()
            .and_then(|p| std::fs::read(p).ok())
            .map_or_else(
                || "unknown".to_string(),
                |bytes| {
                    let mut h = ChunkHash::new();
                    h.update(&bytes);
                    format!("{:016x}", h.finish())
                },
            );
        format!("{} {exe}", env!("CARGO_PKG_VERSION"))
    })
}

/// The scene a render shows: [`super::scene_hash`] of its description and
/// the size and modification time of every file it reads (a cache
/// simulated again under the same name is another scene).
pub fn scene_fingerprint(desc: &SceneDesc) -> String {
    let mut files: Vec<&Path> = desc.volumes.iter().map(|v| v.file.as_path()).collect();
    files.extend(desc.meshes.iter().map(|m| m.file.as_path()));
    if let EnvironmentDesc::Map { path, .. } = &desc.environment {
        files.push(path);
    }
    let mut h = ChunkHash::new();
    for f in files {
        h.update(f.as_os_str().as_encoded_bytes());
        if let Ok(m) = std::fs::metadata(f) {
            h.update(&m.len().to_le_bytes());
            if let Ok(t) = m.modified() {
                if let Ok(d) = t.duration_since(std::time::UNIX_EPOCH) {
                    h.update(&d.as_nanos().to_le_bytes());
                }
            }
        }
    }
    // What only changes how the sums are shown is not part of it.
    let mut d = desc.clone();
    d.render.exposure = 0.0;
    d.render.denoise_quality = crate::scene::DenoiseQuality::High;
    format!("{} {:016x}", super::scene_hash(&d), h.finish())
}

/// What a state must match to be resumed: which render it is of.
#[derive(Debug, Clone, PartialEq)]
pub struct Identity {
    pub binary: String,
    pub scene: String,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    pub region: Region,
    pub integrator: String,
    pub aovs: bool,
    pub guides: bool,
    pub half: bool,
}

impl Identity {
    /// The identity of a render of `desc` over `region` with `integrator`
    /// into `film`.
    pub fn of(desc: &SceneDesc, integrator: &str, film: &Film) -> Self {
        Self {
            binary: binary_fingerprint().to_string(),
            scene: scene_fingerprint(desc),
            seed: desc.render.seed,
            width: film.width,
            height: film.height,
            region: film.region,
            integrator: integrator.to_string(),
            aovs: film.has_aovs(),
            guides: film.has_guides(),
            half: film.has_half(),
        }
    }

    fn lines(&self) -> Vec<(&'static str, String)> {
        vec![
            // In the order of the reasons given for a mismatch: the most
            // telling first, the scene (which holds the size and seed too)
            // last.
            ("binary", self.binary.clone()),
            ("size", format!("{}x{}", self.width, self.height)),
            ("region", self.region.to_string()),
            ("seed", self.seed.to_string()),
            ("integrator", self.integrator.clone()),
            ("aovs", self.aovs.to_string()),
            ("guides", self.guides.to_string()),
            ("half", self.half.to_string()),
            ("scene", self.scene.clone()),
        ]
    }

    /// Why a state of identity `other` is not of this render, if it is not.
    fn mismatch(&self, other: &[(String, String)]) -> Option<String> {
        let get = |k: &str| other.iter().find(|(x, _)| x == k).map(|(_, v)| v.as_str());
        for (k, mine) in self.lines() {
            let theirs = get(k).unwrap_or("(none)");
            if theirs == mine {
                continue;
            }
            return Some(match k {
                "binary" => format!(
                    "it was written by another build of vdbphoton ({theirs}; this is {mine})"
                ),
                "scene" => {
                    "it is of another scene (its description or its input files changed)".into()
                }
                "size" => format!("it is of a {theirs} image, not {mine}"),
                "region" => format!("it is of the pixels {theirs}, not {mine}"),
                "aovs" | "guides" | "half" => format!(
                    "its film {} {k}",
                    if theirs == "true" { "has" } else { "has no" }
                ),
                _ => format!("it is of {k} {theirs}, not {mine}"),
            });
        }
        None
    }
}

/// Where a render is: the passes done, the seconds they took (a time
/// budget counts them) and the last pass's (which decides whether another
/// fits).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Position {
    pub passes: u32,
    pub seconds: f64,
    pub last_pass: f64,
}

/// A state read back: where the render was, its integrator's state and its
/// film.
#[derive(Debug, Clone)]
pub struct Resumed {
    pub at: Position,
    pub integrator: PassState,
    pub film: Film,
}

/// Writes the state of a render (atomically, synced to disk before it
/// replaces the previous one, so that a power cut leaves the old state or
/// the new, whole).
pub fn write(
    path: &Path,
    id: &Identity,
    at: Position,
    integrator: &PassState,
    film: &Film,
) -> Result<()> {
    let io = |e: std::io::Error| {
        Error::Argument(format!(
            "cannot write the render state '{}': {e}",
            path.display()
        ))
    };
    crate::atomic::replace_with(
        path,
        |temp| {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(temp)
                .map_err(io)?;
            let mut w = Hashing {
                inner: std::io::BufWriter::with_capacity(1 << 20, file),
                hash: ChunkHash::new(),
            };
            let mut head = format!("{MAGIC}\n");
            for (k, v) in id.lines() {
                head.push_str(&format!("{k}={v}\n"));
            }
            head.push_str(&format!(
                "passes={}\nseconds={}\nlast_pass={}\n",
                at.passes, at.seconds, at.last_pass
            ));
            for (k, v) in integrator {
                head.push_str(&format!("integrator.{k}={v}\n"));
            }
            head.push_str(&format!("film_bytes={}\n\n", film.sums_bytes()));
            w.write_all(head.as_bytes()).map_err(io)?;
            film.write_sums(&mut w).map_err(io)?;
            crash_for_test(at.passes, &mut w).map_err(io)?;
            let sum = w.hash.finish();
            let mut inner = w.inner;
            inner.write_all(&sum.to_le_bytes()).map_err(io)?;
            let file = inner.into_inner().map_err(|e| io(e.into_error()))?;
            file.sync_all().map_err(io)?;
            Ok(())
        },
        io,
    )
}

/// Fault injection for the tests of a power cut: with
/// `VDBPHOTON_TEST_DIE_WRITING_STATE=N`, the process kills itself (SIGKILL)
/// while writing the state of a checkpoint after `N` passes or more, its
/// film written but not its checksum, as a power cut or an OOM kill would.
fn crash_for_test(passes: u32, w: &mut impl Write) -> std::io::Result<()> {
    let die_at = std::env::var("VDBPHOTON_TEST_DIE_WRITING_STATE")
        .ok()
        .and_then(|v| v.parse::<u32>().ok());
    if die_at.is_some_and(|n| passes >= n) {
        w.flush()?;
        // SAFETY: raising a signal in our own process.
        unsafe {
            libc::raise(libc::SIGKILL);
        }
    }
    Ok(())
}

/// The integrator the state at `path` was made with, when it is a state
/// that names one (its header alone is read; [`read`] checks the rest).
pub fn integrator_of(path: &Path) -> Option<String> {
    use std::io::BufRead;
    let file = File::open(path).ok()?;
    let mut lines = std::io::BufReader::new(file).lines();
    if lines.next()?.ok()? != MAGIC {
        return None;
    }
    for line in lines.take(64) {
        let line = line.ok()?;
        if line.is_empty() {
            break;
        }
        if let Some(name) = line.strip_prefix("integrator=") {
            return Some(name.to_string());
        }
    }
    None
}

/// Reads the state at `path` when it belongs to the render of identity
/// `id`, whose empty film is `empty`: `Ok(None)` when there is none,
/// `Err(why)` when it is not this render's or is damaged.
pub fn read(
    path: &Path,
    id: &Identity,
    empty: &Film,
) -> std::result::Result<Option<Resumed>, String> {
    use std::io::{BufRead, Seek};
    let mut file = match File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("cannot read it: {e}")),
    };
    let io = |e: std::io::Error| format!("cannot read it: {e}");
    let damaged = |what: &str| format!("it is damaged ({what})");
    let len = file.metadata().map_err(io)?.len();
    let magic = format!("{MAGIC}\n");
    let mut head = vec![0u8; magic.len().min(len as usize)];
    file.read_exact(&mut head).map_err(io)?;
    if head != magic.as_bytes() {
        return Err(if head.starts_with(b"vdbphoton render state") {
            "it is of another version of the state format".into()
        } else {
            "it is not a vdbphoton render state".into()
        });
    }
    if len < magic.len() as u64 + 8 {
        return Err(damaged("truncated"));
    }
    // The checksum over everything before it, read a chunk at a time.
    file.rewind().map_err(io)?;
    let mut h = ChunkHash::new();
    let mut buf = vec![0u8; HASH_CHUNK];
    let mut left = len - 8;
    while left > 0 {
        let n = left.min(HASH_CHUNK as u64) as usize;
        file.read_exact(&mut buf[..n]).map_err(io)?;
        h.update(&buf[..n]);
        left -= n as u64;
    }
    let mut sum = [0u8; 8];
    file.read_exact(&mut sum).map_err(io)?;
    if h.finish().to_le_bytes() != sum {
        return Err(damaged(
            "its checksum does not match: truncated or overwritten",
        ));
    }
    // The header's lines, up to the blank line, then the film.
    file.rewind().map_err(io)?;
    let mut r = std::io::BufReader::with_capacity(1 << 20, file);
    let mut pairs: Vec<(String, String)> = Vec::new();
    let mut line = String::new();
    r.read_line(&mut line).map_err(io)?;
    loop {
        line.clear();
        if r.read_line(&mut line)
            .map_err(|_| damaged("header not text"))?
            == 0
        {
            return Err(damaged("no end of header"));
        }
        let l = line.trim_end_matches('\n');
        if l.is_empty() {
            break;
        }
        if let Some((k, v)) = l.split_once('=') {
            pairs.push((k.to_string(), v.to_string()));
        }
    }
    if let Some(why) = id.mismatch(&pairs) {
        return Err(why);
    }
    let get = |k: &str| {
        pairs
            .iter()
            .find(|(x, _)| x == k)
            .map(|(_, v)| v.as_str())
            .ok_or_else(|| damaged(&format!("no {k}")))
    };
    let num = |k: &str| -> std::result::Result<f64, String> {
        get(k)?
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x >= 0.0)
            .ok_or_else(|| damaged(&format!("bad {k}")))
    };
    if get("film_bytes")? != empty.sums_bytes().to_string() {
        return Err(damaged("its film is not of this render's size"));
    }
    let at = Position {
        passes: get("passes")?.parse().map_err(|_| damaged("bad passes"))?,
        seconds: num("seconds")?,
        last_pass: num("last_pass")?,
    };
    let integrator = pairs
        .iter()
        .filter_map(|(k, v)| {
            k.strip_prefix("integrator.")
                .map(|k| (k.to_string(), v.clone()))
        })
        .collect();
    let mut film = empty.clone();
    film.read_sums(&mut r).map_err(|e| damaged(&e))?;
    if r.stream_position().map_err(io)? != len - 8 {
        return Err(damaged("more bytes than its film"));
    }
    Ok(Some(Resumed {
        at,
        integrator,
        film,
    }))
}

/// The lock a render holds on its output while it checkpoints or resumes
/// (released when dropped, or by the kernel when the process dies).
pub struct Lock {
    path: PathBuf,
    _file: File,
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Removed while still held: a render waiting for it finds the
        // file gone and makes its own (see `lock`).
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Takes the lock of the render writing `output`, or says which process
/// holds it; with `clean`, removes what a killed render of `output` left
/// half-written (its EXR's and state's temporaries).
pub fn lock(output: &Path, clean: bool) -> Result<Lock> {
    let path = lock_path(output);
    let err = |e: std::io::Error| {
        Error::Argument(format!("cannot make the lock '{}': {e}", path.display()))
    };
    loop {
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(err)?;
        // flock (not `File::try_lock`, newer than the crate's Rust 1.88).
        use std::os::fd::AsRawFd;
        // SAFETY: flock on a descriptor this function owns.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::WouldBlock {
                return Err(err(e));
            }
            let mut holder = String::new();
            let _ = file.read_to_string(&mut holder);
            return Err(Error::Argument(format!(
                "another render of '{}' is running ({}holds the lock '{}'); wait for it or stop it",
                output.display(),
                match holder.trim() {
                    "" => String::new(),
                    h => format!("{h} "),
                },
                path.display()
            )));
        }
        // The holder before us may have removed the file between our open
        // and our lock: then we hold a lock on nothing; take it again.
        let same = match (file.metadata(), std::fs::metadata(&path)) {
            (Ok(a), Ok(b)) => {
                use std::os::unix::fs::MetadataExt;
                a.ino() == b.ino() && a.dev() == b.dev()
            }
            _ => false,
        };
        if !same {
            continue;
        }
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        let _ = file.set_len(0);
        let _ = write!(file, "process {} on {}", std::process::id(), host.trim());
        if clean {
            remove_stale_temporaries(output);
        }
        return Ok(Lock { path, _file: file });
    }
}

/// Removes what a killed render of `output` left half-written: the
/// temporaries of its EXR and state (`crate::atomic`), which no live
/// render can be writing while we hold the lock.
fn remove_stale_temporaries(output: &Path) {
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Some(name) = output.file_name().and_then(|n| n.to_str()) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let ours = [format!(".{name}.tmp-"), format!(".{name}.vdbstate.tmp-")];
    for e in entries.flatten() {
        let f = e.file_name();
        if f.to_str()
            .is_some_and(|f| ours.iter().any(|p| f.starts_with(p.as_str())))
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
}
