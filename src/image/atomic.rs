//! Atomic file output: write a temporary file next to the target, then rename.

use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::ImageError;

/// Distinguishes temporaries of concurrent writes from the same process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Removes the temporary file unless disarmed (also on panic in the writer).
struct TempGuard {
    path: Option<PathBuf>,
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if let Some(path) = self.path.take() {
            let _ = fs::remove_file(path);
        }
    }
}

/// The temporary name used for `target`: `.<name>.tmp-<pid>-<n>` in the same
/// directory (so the final `rename` stays on one file system).
fn temp_path(target: &Path) -> Result<PathBuf, ImageError> {
    let name = target.file_name().ok_or_else(|| ImageError::Encode {
        path: target.to_path_buf(),
        reason: "the path does not name a file".into(),
    })?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".tmp-{}-{n}", std::process::id()));
    Ok(target.with_file_name(temp_name))
}

/// Write `target` atomically: `write` fills a buffered temporary file in the
/// same directory, which is then renamed over `target`. On any error (or a
/// panic in `write`) the temporary is removed and `target` is left as it was.
/// The parent directory is not created: a missing one is an error naming
/// `target`. No fsync is done.
pub(crate) fn write_atomically<F>(target: &Path, write: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<(), ImageError>,
{
    let io_err = |source: std::io::Error| ImageError::Write {
        path: target.to_path_buf(),
        source,
    };
    let temp = temp_path(target)?;
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temp)
        .map_err(io_err)?;
    let mut guard = TempGuard {
        path: Some(temp.clone()),
    };
    let mut writer = BufWriter::new(file);
    write(&mut writer)?;
    writer.flush().map_err(io_err)?;
    let file = writer.into_inner().map_err(|e| io_err(e.into_error()))?;
    drop(file);
    fs::rename(&temp, target).map_err(io_err)?;
    guard.path = None;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn success_leaves_only_target() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.bin");
        write_atomically(&target, |w| {
            w.write_all(b"hello").unwrap();
            Ok(())
        })
        .unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"hello");
        assert_eq!(entries(dir.path()), vec!["a.bin"]);
    }

    #[test]
    fn failing_writer_keeps_old_target_and_removes_temp() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.bin");
        fs::write(&target, b"old").unwrap();
        let err = write_atomically(&target, |w| {
            w.write_all(&[7u8; 100_000]).unwrap();
            Err(ImageError::InvalidArgument("boom".into()))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "boom");
        assert_eq!(fs::read(&target).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["a.bin"]);
    }

    #[test]
    fn panicking_writer_removes_temp() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("p.bin");
        let r = std::panic::catch_unwind(|| {
            let _ = write_atomically(&target, |w| {
                w.write_all(b"partial").unwrap();
                panic!("writer panicked");
            });
        });
        assert!(r.is_err());
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn temp_name_is_hidden_in_same_dir() {
        let t = temp_path(Path::new("out/x.exr")).unwrap();
        assert_eq!(t.parent().unwrap(), Path::new("out"));
        let name = t.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(".x.exr.tmp-"), "{name}");
        assert!(temp_path(Path::new("/")).is_err());
    }
}
