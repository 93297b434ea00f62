//! The fixed CI campaign of the fuzz harness (tools/fuzz/README.md): 1,000
//! mutated `.vdb` files, 1,000 mutated scenes and 100 renders of a mutated
//! scene with a mutated VDB, each in a child process. Not one may crash,
//! hang (over 2 s), take more than 200 MB, be accepted when it should not
//! be, or be refused without one line naming the file. A few minutes on two
//! cores; the full benchmark is `vdbfuzz run` with larger counts.

mod common;

use std::process::Command;

#[test]
fn fixed_campaign_finds_nothing() {
    let work = common::tempdir();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vdbfuzz"));
    cmd.args([
        "run",
        "--vdb",
        "1000",
        "--scenes",
        "1000",
        "--renders",
        "100",
    ])
    .args(["--seed", "24", "--jobs", "2"])
    .arg("--work")
    .arg(work.path())
    .arg("--vdbphoton")
    .arg(env!("CARGO_BIN_EXE_vdbphoton"));
    if let Some(dir) = common::real_data() {
        cmd.arg("--real-data").arg(dir);
    }
    let out = cmd.output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    println!("{report}");
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "the campaign found failures:\n{report}"
    );
    assert!(report.contains("2100 inputs"), "{report}");
}
