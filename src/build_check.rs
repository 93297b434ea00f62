//! The system-package check that `build.rs` runs before compiling `cpp/`.
//!
//! It lives here, outside the library (no `mod` in `lib.rs`), so that both
//! `build.rs` and `tests/build_check.rs` include it with `#[path]`: the
//! message a newcomer sees when OpenVDB's development files are missing is
//! then tested, not only written.

use std::path::Path;

/// Where Debian's packages put their headers.
pub const INCLUDE_DIRS: [&str; 2] = ["/usr/include", "/usr/local/include"];

/// One header per Debian 12 package the bridge needs: OpenVDB's headers
/// include Boost and TBB, and the link needs Imath (without it:
/// `imath_half_to_float_table`).
pub const REQUIRED: [(&str, &str); 4] = [
    ("openvdb/openvdb.h", "libopenvdb-dev"),
    ("boost/version.hpp", "libboost-dev"),
    ("tbb/tbb.h", "libtbb-dev"),
    ("Imath/ImathConfig.h", "libimath-dev"),
];

/// The packages whose header is in none of `include_dirs`, in `REQUIRED`'s
/// order.
pub fn missing_packages(include_dirs: &[&Path]) -> Vec<&'static str> {
    REQUIRED
        .iter()
        .filter(|(h, _)| !include_dirs.iter().any(|d| d.join(h).is_file()))
        .map(|(_, p)| *p)
        .collect()
}

/// The message the build stops with: what is missing and the one command
/// that installs every package in `REQUIRED`, instead of a wall of compiler
/// errors.
pub fn missing_message(missing: &[&str]) -> String {
    format!(
        "vdbphoton needs the OpenVDB 10 development files, which are not installed \
         (missing: {}).\nInstall them with:\n\n    sudo apt-get install -y {}\n",
        missing.join(" "),
        REQUIRED.map(|(_, p)| p).join(" ")
    )
}
