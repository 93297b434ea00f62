//! Wavefront OBJ meshes, read with `tobj`: the positions (`v`) and faces
//! (`f`, fanned into triangles) of every object and group in the file,
//! merged into one mesh, with their normals (`vn`) and texture coordinates
//! (`vt`) when every object has them; materials are not read, and no
//! `.mtl` file is opened.

use super::TriangleMesh;
use crate::error::{Error, Result};
use glam::{Vec2, Vec3};
use std::io::BufReader;
use std::path::Path;

pub(super) fn read(path: &Path) -> Result<TriangleMesh> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    // One index for positions, normals and texture coordinates (tobj
    // splits vertices whose corners differ).
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj_buf(&mut BufReader::new(file), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| Error::file(path, format!("not a readable OBJ mesh: {e}")))?;
    let mut mesh = TriangleMesh::default();
    for m in models {
        let base = u32::try_from(mesh.positions.len())
            .map_err(|_| Error::file(path, "more than 2^32 vertices"))?;
        let m = m.mesh;
        let n = m.positions.len() / 3;
        // Normals and texture coordinates only if every object has them
        // (an object without makes the mesh go without).
        let first = mesh.positions.is_empty();
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        if m.normals.len() == 3 * n && (first || !mesh.normals.is_empty()) {
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|p| Vec3::new(p[0], p[1], p[2])),
            );
        } else {
            mesh.normals.clear();
        }
        if m.texcoords.len() == 2 * n && (first || !mesh.uvs.is_empty()) {
            mesh.uvs
                .extend(m.texcoords.chunks_exact(2).map(|p| Vec2::new(p[0], p[1])));
        } else {
            mesh.uvs.clear();
        }
        mesh.triangles.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]].map(|i| i.saturating_add(base))),
        );
    }
    Ok(mesh)
}

/// Vertices and faces of the OBJ file at `path`, counted by their lines
/// (`v ` and `f `) in one pass over its bytes, without parsing them: a
/// face counts as one triangle (a polygon gives more, and is counted low).
pub(super) fn size(path: &Path) -> Result<super::MeshSize> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut buf = vec![0u8; 1 << 20];
    let (mut vertices, mut triangles) = (0u64, 0u64);
    // Where the scan is in a line: at its start, after a `v` or an `f`
    // there, or anywhere else.
    #[derive(Clone, Copy, PartialEq)]
    enum At {
        Start,
        V,
        F,
        Rest,
    }
    let mut at = At::Start;
    loop {
        let n = file.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        for &b in &buf[..n] {
            at = match (at, b) {
                (_, b'\n') => At::Start,
                (At::Start, b'v') => At::V,
                (At::Start, b'f') => At::F,
                (At::V, b' ' | b'\t') => {
                    vertices += 1;
                    At::Rest
                }
                (At::F, b' ' | b'\t') => {
                    triangles += 1;
                    At::Rest
                }
                _ => At::Rest,
            };
        }
    }
    Ok(super::MeshSize {
        vertices,
        triangles,
    })
}
