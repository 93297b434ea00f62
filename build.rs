//! Builds the C++ half of the OpenVDB bridge (`cpp/`) against Debian's
//! OpenVDB 10 (`libopenvdb-dev`). OpenVDB's headers include Boost and TBB;
//! linking needs openvdb, tbb and Imath (without Imath the link fails on
//! `imath_half_to_float_table`).

use std::path::Path;

#[path = "src/build_check.rs"]
mod build_check;

fn main() {
    let include_dirs = build_check::INCLUDE_DIRS.map(Path::new);
    let missing = build_check::missing_packages(&include_dirs);
    if !missing.is_empty() {
        // Cargo shows a failed build script's stderr: one clear message and
        // exit status 1, no panic and no compiler errors after it.
        eprintln!("\n{}", build_check::missing_message(&missing));
        std::process::exit(1);
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
    println!("cargo:rerun-if-changed=src/build_check.rs");
}
