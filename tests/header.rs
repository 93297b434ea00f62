//! The Rust header check reads the grid table as OpenVDB writes it.

mod common;

use vdbphoton::generate;
use vdbphoton::vdb::header::{parse, HeaderError};
use vdbphoton::vdb::{write_vdb, AnyGrid, VdbFile};

#[test]
fn grid_table_of_a_written_file() {
    let dir = common::tempdir();
    let p = dir.path().join("plume.vdb");
    write_vdb(&p, &generate::plume(24, 3).unwrap()).unwrap();
    let f = VdbFile::open(&p).unwrap();
    let h = f.header();
    assert_eq!(h.file_version, 224);
    assert_eq!(h.library_version, (10, 0));
    assert_eq!(h.grids.len(), 4);
    let size = std::fs::metadata(&p).unwrap().len();
    assert_eq!(
        h.grids.last().unwrap().end_pos,
        size,
        "the last grid ends at the file's end"
    );
    for w in h.grids.windows(2) {
        assert!(w[0].end_pos <= w[1].grid_pos);
    }
    let types: Vec<&str> = h.grids.iter().map(|g| g.value_type()).collect();
    assert_eq!(types, ["vec3s", "float", "float", "float"]);
    assert_eq!(h.grids[0].channels(), Some(3));
}

#[test]
fn bytes_that_are_not_a_header() {
    let empty: &[u8] = &[];
    assert_eq!(parse(&mut { empty }, 0).unwrap_err(), HeaderError::Empty);
    let text: &[u8] = b"hello world, this is not a vdb file at all";
    assert_eq!(
        parse(&mut { text }, text.len() as u64).unwrap_err(),
        HeaderError::NotVdb
    );
    // A valid magic number and nothing after it.
    let magic: &[u8] = &[0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0];
    assert!(matches!(
        parse(&mut { magic }, 8).unwrap_err(),
        HeaderError::TruncatedHeader { .. }
    ));
}

#[test]
fn every_prefix_of_a_file_is_refused_cleanly() {
    let dir = common::tempdir();
    let p = dir.path().join("cloud.vdb");
    write_vdb(&p, &[AnyGrid::Float(generate::cloud(16, 1).unwrap())]).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let full = parse(&mut &bytes[..], bytes.len() as u64).unwrap();
    let header_end = full.grids[0].grid_pos as usize;
    for n in 0..bytes.len() {
        let prefix = &bytes[..n];
        let r = parse(&mut { prefix }, n as u64);
        assert!(
            r.is_err(),
            "a {n}-byte prefix was accepted (header ends at {header_end})"
        );
    }
}

#[test]
fn real_files_have_the_grids_the_reference_lists() {
    let Some(dir) = common::real_data() else {
        return;
    };
    let f = VdbFile::open(dir.join("blender_smoke/fluid_data_0025.vdb")).unwrap();
    assert_eq!(
        f.grid_names(),
        ["velocity", "density", "shadow", "temperature", "flame"]
    );
    assert_eq!(f.header().grids.last().unwrap().end_pos, 245188);
    let pig = VdbFile::open(dir.join("external/pig.vdb")).unwrap();
    assert_eq!(pig.header().metadata.len(), 1);
    assert!(pig
        .header()
        .meta_string("creator")
        .unwrap()
        .contains("Houdini"));
}
