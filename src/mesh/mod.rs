//! Triangle meshes read from the files Blender and Houdini write: PLY
//! (ASCII or binary, `ply-rs-bw`) and Wavefront OBJ (`tobj`). Data only:
//! positions and triangles in the file's own (object) space; placing them
//! in the scene and tracing rays against them is `crate::shape`'s.
//!
//! Every reader checks what it read before anything uses it: finite
//! vertices, face indices inside the vertex list, faces that do not repeat
//! a vertex, at least one triangle. A binary PLY whose header announces more
//! data than the file holds is refused from its header alone, before any
//! allocation (a hostile count cannot make us allocate for it). Polygons are
//! cut into triangle fans, as Blender's PLY and OBJ importers do.

mod obj;
mod ply;

use crate::error::{Error, Result};
use glam::{Vec2, Vec3};
use std::path::Path;

/// A triangle mesh: vertex positions and, per triangle, three indices into
/// them (counter-clockwise seen from the front, as the file gives them);
/// per vertex, when the file has them, normals (smooth shading, as Blender
/// writes them) and texture coordinates (its active UV map).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// One per vertex, or none.
    pub normals: Vec<Vec3>,
    /// One per vertex, or none.
    pub uvs: Vec<Vec2>,
}

/// The sizes of a mesh file: its vertices and (at most) its triangles, as
/// its header says (PLY) or as its size allows (OBJ), read without its data
/// for the memory check before a render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeshSize {
    pub vertices: u64,
    pub triangles: u64,
}

/// The file formats read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    Ply,
    Obj,
}

impl MeshFormat {
    /// The format of `path` by its extension (any case).
    pub fn of(path: &Path) -> Option<MeshFormat> {
        let e = path.extension()?.to_str()?.to_ascii_lowercase();
        match e.as_str() {
            "ply" => Some(MeshFormat::Ply),
            "obj" => Some(MeshFormat::Obj),
            _ => None,
        }
    }
}

fn format_of(path: &Path) -> Result<MeshFormat> {
    MeshFormat::of(path).ok_or_else(|| {
        Error::file(
            path,
            "not a mesh file vdbphoton reads: the name must end in .ply or .obj",
        )
    })
}

fn check_file(path: &Path) -> Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::file(path, "is a directory, not a mesh file"));
    }
    Ok(meta)
}

/// The vertex and triangle counts of the mesh file at `path`, from its
/// header (PLY: exact vertices, and faces taken as triangles) or counted
/// by its lines (OBJ), without reading the data.
pub fn size_of_file(path: &Path) -> Result<MeshSize> {
    let format = format_of(path)?;
    check_file(path)?;
    match format {
        MeshFormat::Ply => ply::size(path),
        MeshFormat::Obj => obj::size(path),
    }
}

/// Reads the mesh at `path` (PLY or OBJ by its extension) and checks it.
pub fn read(path: &Path) -> Result<TriangleMesh> {
    let format = format_of(path)?;
    check_file(path)?;
    let mesh = match format {
        MeshFormat::Ply => ply::read(path)?,
        MeshFormat::Obj => obj::read(path)?,
    };
    mesh.validate().map_err(|m| Error::file(path, m))?;
    Ok(mesh)
}

/// Appends the triangle fan of `face` (`v0 v1 v2`, `v0 v2 v3`, ...) to
/// `out`; a face of fewer than three vertices is an error (`index`: the
/// face's number, for the message).
pub(crate) fn fan(face: &[u32], index: usize, out: &mut Vec<[u32; 3]>) -> Result<(), String> {
    if face.len() < 3 {
        return Err(format!(
            "face {index} has {} vertices; a face needs at least 3",
            face.len()
        ));
    }
    for k in 1..face.len() - 1 {
        out.push([face[0], face[k], face[k + 1]]);
    }
    Ok(())
}

impl TriangleMesh {
    /// Checks what a renderer relies on: at least one triangle, finite
    /// vertices, indices inside the vertex list, and no triangle that
    /// repeats a vertex (a degenerate face: the file is damaged, or not the
    /// mesh its writer meant).
    pub fn validate(&self) -> Result<(), String> {
        if self.triangles.is_empty() {
            return Err("the mesh has no faces (nothing to render)".into());
        }
        if let Some((i, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(format!(
                "vertex {i} is not finite ({}, {}, {}); fix the mesh or its export",
                p.x, p.y, p.z
            ));
        }
        let n = self.positions.len() as u64;
        for (what, len) in [("normals", self.normals.len()), ("uvs", self.uvs.len())] {
            if len != 0 && len as u64 != n {
                return Err(format!("{len} vertex {what} for {n} vertices"));
            }
        }
        if let Some((i, v)) = self
            .normals
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite())
        {
            return Err(format!(
                "the normal of vertex {i} is not finite ({}, {}, {}); fix the mesh or its export",
                v.x, v.y, v.z
            ));
        }
        if let Some((i, v)) = self.uvs.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!(
                "the texture coordinates of vertex {i} are not finite ({}, {}); fix the mesh or its export",
                v.x, v.y
            ));
        }
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(v) = t.iter().find(|&&v| v as u64 >= n) {
                return Err(format!(
                    "triangle {i} refers to vertex {v}, but the file has {n} vertices (0 to {})",
                    n.saturating_sub(1)
                ));
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(format!(
                    "triangle {i} repeats a vertex ({} {} {}): a degenerate face",
                    t[0], t[1], t[2]
                ));
            }
        }
        Ok(())
    }

    /// Bytes the mesh takes in memory.
    pub fn memory_bytes(&self) -> usize {
        self.positions.capacity() * std::mem::size_of::<Vec3>()
            + self.triangles.capacity() * std::mem::size_of::<[u32; 3]>()
            + self.normals.capacity() * std::mem::size_of::<Vec3>()
            + self.uvs.capacity() * std::mem::size_of::<Vec2>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygons_become_fans() {
        let mut out = Vec::new();
        fan(&[4, 5, 6, 7, 8], 0, &mut out).unwrap();
        assert_eq!(out, vec![[4, 5, 6], [4, 6, 7], [4, 7, 8]]);
        assert!(fan(&[1, 2], 3, &mut out).unwrap_err().contains("face 3"));
    }

    #[test]
    fn validation_names_what_is_wrong() {
        let good = TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        };
        assert!(good.validate().is_ok());
        let mut m = good.clone();
        m.positions[1].y = f32::NAN;
        assert!(m.validate().unwrap_err().contains("vertex 1 is not finite"));
        let mut m = good.clone();
        m.triangles[0] = [0, 1, 3];
        assert!(m.validate().unwrap_err().contains("refers to vertex 3"));
        let mut m = good.clone();
        m.triangles[0] = [0, 1, 1];
        assert!(m.validate().unwrap_err().contains("degenerate"));
        let mut m = good.clone();
        m.normals = vec![Vec3::Z; 2];
        assert!(m.validate().unwrap_err().contains("2 vertex normals for 3"));
        m.normals = vec![Vec3::Z, Vec3::Z, Vec3::NAN];
        assert!(m.validate().unwrap_err().contains("normal of vertex 2"));
        let m = TriangleMesh {
            triangles: vec![],
            ..good
        };
        assert!(m.validate().unwrap_err().contains("no faces"));
    }
}
