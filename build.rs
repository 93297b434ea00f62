//! Builds the C++ half of the OpenVDB bridge (`cpp/`) against Debian's
//! OpenVDB 10 (`libopenvdb-dev`). OpenVDB's headers include Boost and TBB;
//! linking needs openvdb, tbb and Imath (without Imath the link fails on
//! `imath_half_to_float_table`).

use std::path::Path;

const PACKAGES: &str = "libopenvdb-dev libboost-dev libtbb-dev libimath-dev";

fn main() {
    let include_dirs = ["/usr/include", "/usr/local/include"];
    let has = |h: &str| include_dirs.iter().any(|d| Path::new(d).join(h).exists());
    let missing: Vec<&str> = [
        ("openvdb/openvdb.h", "libopenvdb-dev"),
        ("boost/version.hpp", "libboost-dev"),
        ("tbb/tbb.h", "libtbb-dev"),
        ("Imath/ImathConfig.h", "libimath-dev"),
    ]
    .iter()
    .filter(|(h, _)| !has(h))
    .map(|(_, p)| *p)
    .collect();
    if !missing.is_empty() {
        eprintln!(
            "\nvdbphoton needs the OpenVDB 10 development files, which are not installed \
             (missing: {}).\nInstall them with:\n\n    sudo apt-get install -y {PACKAGES}\n",
            missing.join(" ")
        );
        panic!("missing system packages: {}", missing.join(" "));
    }

    cxx_build::bridge("src/vdb/ffi.rs")
        .file("cpp/vdb_bridge.cc")
        .std("c++17")
        .include("/usr/include/Imath")
        .flag_if_supported("-Wno-deprecated-declarations")
        .flag_if_supported("-Wno-unused-parameter")
        .opt_level(2)
        .compile("vdbphoton_bridge");

    for lib in ["openvdb", "tbb", "Imath-3_1"] {
        println!("cargo:rustc-link-lib={lib}");
    }
    println!("cargo:rerun-if-changed=cpp/vdb_bridge.cc");
    println!("cargo:rerun-if-changed=cpp/vdb_bridge.h");
    println!("cargo:rerun-if-changed=src/vdb/ffi.rs");
}
