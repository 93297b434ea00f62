//! AFL++ target: the `.vdb` reader (header check, grid walk, OpenVDB, grid
//! build), in process, on the bytes AFL gives. A crash, an abort, a panic
//! or a grid accepted unlike its header (the oracle of `vdbfuzz`) is a
//! finding; a refusal is fine.

#[path = "../../../oracle.rs"]
#[allow(dead_code)]
mod oracle;

use std::io::Write;

fn main() {
    // OpenVDB opens files by name: the input goes to a file of this
    // process's own, rewritten for each input.
    let dir = std::env::var_os("AFL_TARGET_TMP")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(std::env::temp_dir);
    let path = dir.join(format!("afl_vdb_{}.vdb", std::process::id()));
    afl::fuzz!(|data: &[u8]| {
        let mut f = std::fs::File::create(&path).expect("scratch file");
        f.write_all(data).expect("scratch file");
        drop(f);
        if let Ok(r) = oracle::read_vdb(&path) {
            if !r.mismatch.is_empty() {
                panic!("accepted a grid unlike its header: {:?}", r.mismatch);
            }
        }
    });
    let _ = std::fs::remove_file(&path);
    // With a finite `AFL_FUZZER_LOOPCOUNT` (1: a fresh process per input,
    // so that a crash comes with the input that caused it) the loop ends;
    // a normal exit then ran past AFL's time limit on every input, `_exit`
    // does not.
    // SAFETY: ends the process; nothing is left to flush.
    unsafe { _exit(0) };
}

extern "C" {
    fn _exit(code: i32) -> !;
}
