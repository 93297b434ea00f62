//! The image writers' use of [`crate::atomic`].

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use super::ImageError;

/// [`crate::atomic::write_atomically`] with I/O errors naming `target`.
pub(crate) fn write_atomically<F>(target: &Path, write: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<(), ImageError>,
{
    crate::atomic::write_atomically(
        target,
        |source| ImageError::Write {
            path: target.to_path_buf(),
            source,
        },
        write,
    )
}
