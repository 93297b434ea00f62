//! The message `build.rs` stops with when OpenVDB's development files are
//! missing (the same file `build.rs` includes).

#[path = "../src/build_check.rs"]
mod build_check;

use build_check::{missing_message, missing_packages, INCLUDE_DIRS, REQUIRED};
use std::path::Path;

fn touch(dir: &Path, header: &str) {
    let p = dir.join(header);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, "").unwrap();
}

#[test]
fn every_missing_header_names_its_package() {
    let empty = tempfile::tempdir().unwrap();
    assert_eq!(
        missing_packages(&[empty.path()]),
        [
            "libopenvdb-dev",
            "libboost-dev",
            "libtbb-dev",
            "libimath-dev"
        ]
    );
    // Headers split over two include folders count as present.
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    touch(a.path(), "openvdb/openvdb.h");
    touch(a.path(), "tbb/tbb.h");
    touch(b.path(), "Imath/ImathConfig.h");
    assert_eq!(missing_packages(&[a.path(), b.path()]), ["libboost-dev"]);
    touch(b.path(), "boost/version.hpp");
    assert!(missing_packages(&[a.path(), b.path()]).is_empty());
    // A folder where a header should be does not count.
    let c = tempfile::tempdir().unwrap();
    for (h, _) in REQUIRED {
        touch(c.path(), h);
    }
    std::fs::remove_file(c.path().join("tbb/tbb.h")).unwrap();
    std::fs::create_dir(c.path().join("tbb/tbb.h")).unwrap();
    assert_eq!(missing_packages(&[c.path()]), ["libtbb-dev"]);
}

#[test]
fn the_message_says_what_to_install() {
    let m = missing_message(&["libopenvdb-dev", "libimath-dev"]);
    assert!(m.contains("(missing: libopenvdb-dev libimath-dev)"), "{m}");
    assert!(
        m.contains("sudo apt-get install -y libopenvdb-dev libboost-dev libtbb-dev libimath-dev"),
        "{m}"
    );
    // Every package the check knows is in the install command.
    let command = m.lines().find(|l| l.contains("apt-get install")).unwrap();
    for (_, p) in REQUIRED {
        assert!(command.split(' ').any(|q| q == p), "{p} not in {command}");
    }
}

#[test]
fn this_machine_has_what_the_build_needed() {
    // The crate built, so the real include folders passed the check.
    assert!(missing_packages(&INCLUDE_DIRS.map(Path::new)).is_empty());
}

#[test]
fn setup_and_ci_install_every_package_the_build_needs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for script in ["scripts/setup.sh", ".ci/run"] {
        let text = std::fs::read_to_string(root.join(script)).unwrap();
        for (_, p) in REQUIRED {
            assert!(
                text.lines().any(
                    |l| (l.contains("PACKAGES=") || l.contains("apt-get install"))
                        && l.split([' ', '"']).any(|w| w == p)
                ),
                "{script} does not install {p}"
            );
        }
    }
}
