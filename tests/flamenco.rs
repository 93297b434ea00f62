//! The Flamenco 3 job type (`tools/flamenco/vdbphoton.js`): runs its Node
//! harness, `tools/flamenco/test_vdbphoton.js`, which compiles jobs through
//! stubs of Flamenco's job-compiler API and checks every task, command and
//! dependency (see `tools/flamenco/README.md`).
//!
//! Needs Node.js (`node`, Debian's `nodejs` package; no npm packages). When
//! it is missing the test is skipped with a note, except on CI
//! (`CI=true`), where it fails: CI installs nodejs.

use std::io::ErrorKind;
use std::path::Path;
use std::process::{Command, Output};

/// Runs the harness with the first Node.js executable found (`node`, or
/// `nodejs` as older Debian releases name it); `None` when neither exists.
fn run_harness(root: &Path, script: &Path) -> Option<(String, Output)> {
    for exe in ["node", "nodejs"] {
        match Command::new(exe).arg(script).current_dir(root).output() {
            Ok(out) => return Some((exe.to_string(), out)),
            Err(e) if e.kind() == ErrorKind::NotFound => continue,
            Err(e) => panic!("could not run `{exe} {}`: {e}", script.display()),
        }
    }
    None
}

#[test]
fn flamenco_job_type_harness_passes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let script = root.join("tools/flamenco/test_vdbphoton.js");
    assert!(
        script.is_file(),
        "the harness {} is missing",
        script.display()
    );

    let Some((exe, out)) = run_harness(root, &script) else {
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!(
                "Node.js (`node`) is not installed, and CI=true: CI must install \
                 the nodejs package to check the Flamenco job type"
            );
        }
        eprintln!(
            "note: skipping the Flamenco job type check: Node.js (`node`) is not \
             installed (apt install nodejs; no npm packages are needed)"
        );
        return;
    };

    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "`{exe} tools/flamenco/test_vdbphoton.js` failed ({}):\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
        out.status
    );
    // The harness ends with "N checks passed"; a run that exits 0 without it
    // did not run the checks (e.g. an early `process.exit(0)`).
    let summary = stdout
        .lines()
        .rev()
        .find(|l| l.ends_with(" checks passed"))
        .unwrap_or_else(|| panic!("no 'N checks passed' line in the output:\n{stdout}\n{stderr}"));
    let n: usize = summary
        .trim_end_matches(" checks passed")
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("unexpected summary line '{summary}'"));
    assert!(n > 0, "the harness ran no checks:\n{stdout}");
}
