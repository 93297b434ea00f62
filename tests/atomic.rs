//! `vdbphoton::atomic`: a write either replaces the target whole or leaves
//! it as it was, with no temporary file left behind.

mod common;

use std::fs;
use std::io::Write;
use std::path::Path;
use vdbphoton::atomic::{temp_path, write_atomically};

#[test]
fn success_leaves_only_target() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("a.bin");
    write_atomically(&target, |e| e, |w| w.write_all(b"hello")).unwrap();
    assert_eq!(fs::read(&target).unwrap(), b"hello");
    assert_eq!(common::dir_entries(dir.path()), vec!["a.bin"]);
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
    assert_eq!(common::dir_entries(dir.path()), vec!["a.bin"]);
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
    assert!(common::dir_entries(dir.path()).is_empty());
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
