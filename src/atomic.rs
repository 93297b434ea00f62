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
