//! Output files appear whole or not at all: every writer of the crate (EXR,
//! PNG, `.vdb`, Mitsuba `.vol`) writes a temporary file beside its target
//! and renames it over the target, so an interrupted or failed write never
//! leaves a partial file, and the previous file survives a failure.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

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
/// directory (so the final `rename` stays on one file system); `None` when
/// the path does not name a file.
pub fn temp_path(target: &Path) -> Option<PathBuf> {
    let name = target.file_name()?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".tmp-{}-{n}", std::process::id()));
    Some(target.with_file_name(temp_name))
}

/// Replaces `target` with the file `write` creates at the path it is given
/// (a fresh temporary name beside `target`), by renaming. On any error (or
/// a panic in `write`) the temporary is removed and `target` is left as it
/// was. The parent directory is not created. `io_err` turns the I/O errors
/// of the rename (and a path that names no file) into the caller's error.
pub fn replace_with<E>(
    target: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
    io_err: impl Fn(io::Error) -> E,
) -> Result<(), E> {
    let temp = temp_path(target).ok_or_else(|| {
        io_err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the path does not name a file",
        ))
    })?;
    let mut guard = TempGuard {
        path: Some(temp.clone()),
    };
    write(&temp)?;
    fs::rename(&temp, target).map_err(&io_err)?;
    guard.path = None;
    Ok(())
}

/// [`replace_with`] for a writer that streams into a buffered file. No
/// fsync is done.
pub fn write_atomically<E>(
    target: &Path,
    io_err: impl Fn(io::Error) -> E,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
) -> Result<(), E> {
    replace_with(
        target,
        |temp| {
            let file = OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(temp)
                .map_err(&io_err)?;
            let mut writer = BufWriter::new(file);
            write(&mut writer)?;
            writer.flush().map_err(&io_err)?;
            let file = writer.into_inner().map_err(|e| io_err(e.into_error()))?;
            drop(file);
            Ok(())
        },
        &io_err,
    )
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
        write_atomically(&target, |e| e, |w| w.write_all(b"hello")).unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"hello");
        assert_eq!(entries(dir.path()), vec!["a.bin"]);
    }

    #[test]
    fn failing_writer_keeps_old_target_and_removes_temp() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.bin");
        fs::write(&target, b"old").unwrap();
        let err = write_atomically(
            &target,
            |e| e.to_string(),
            |w| {
                w.write_all(&[7u8; 100_000]).unwrap();
                Err("boom".to_string())
            },
        )
        .unwrap_err();
        assert_eq!(err, "boom");
        assert_eq!(fs::read(&target).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["a.bin"]);
    }

    #[test]
    fn panicking_writer_removes_temp() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("p.bin");
        let r = std::panic::catch_unwind(|| {
            let _ = write_atomically(
                &target,
                |e| e,
                |w| {
                    w.write_all(b"partial").unwrap();
                    panic!("writer panicked");
                },
            );
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
        assert!(temp_path(Path::new("/")).is_none());
        // Two temporaries for one target differ.
        assert_ne!(temp_path(Path::new("a")), temp_path(Path::new("a")));
    }
}
