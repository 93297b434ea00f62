//! PLY meshes (Turk's Polygon File Format, as Blender, Houdini and most
//! tools write it): the `vertex` element's `x y z` (any numeric type) and
//! the `face` element's `vertex_indices` (or `vertex_index`) list, read
//! with `ply-rs-bw`; every other element and property is read past.

use super::{fan, MeshSize, TriangleMesh};
use crate::error::{Error, Result};
use glam::{Vec2, Vec3};
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    BeginList, DefaultElement, ElementDef, Encoding, Header, Property, PropertyAccess,
    PropertyAccessResult, PropertyType, ScalarType,
};
use std::io::{BufReader, Seek};
use std::path::Path;

/// One vertex: its position (NaN until the file sets it), normal and
/// texture coordinates (NaN when the file has none).
struct Vertex([f64; 8]);

fn number(p: Property) -> Option<f64> {
    Some(match p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex([f64::NAN; 8])
    }
    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        let Some(i) = vertex_slot(name) else {
            return PropertyAccessResult::Ignored;
        };
        match number(p) {
            Some(v) => {
                self.0[i] = v;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::UnsupportedType,
        }
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set_property(name, Property::Double(v as f64))
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set_property(name, Property::Double(v))
    }
}

/// Where a vertex property goes in [`Vertex`]: position, normal, texture
/// coordinates (Blender writes `s t`; others `u v` or `texture_u
/// texture_v`).
fn vertex_slot(name: &str) -> Option<usize> {
    Some(match name {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        "nx" => 3,
        "ny" => 4,
        "nz" => 5,
        "s" | "u" | "texture_u" | "texture_s" => 6,
        "t" | "v" | "texture_v" | "texture_t" => 7,
        _ => return None,
    })
}

/// One face: its vertex indices as the file gives them (any integer type;
/// a negative one becomes out of range).
#[derive(Default)]
struct Face(Vec<u32>);

fn index_list(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        if !index_list(name) {
            return PropertyAccessResult::Ignored;
        }
        fn conv<T: Copy + TryInto<u32>>(v: &[T]) -> Vec<u32> {
            v.iter()
                .map(|&x| x.try_into().unwrap_or(u32::MAX))
                .collect()
        }
        self.0 = match p {
            Property::ListChar(v) => conv(&v),
            Property::ListUChar(v) => conv(&v),
            Property::ListShort(v) => conv(&v),
            Property::ListUShort(v) => conv(&v),
            Property::ListInt(v) => conv(&v),
            Property::ListUInt(v) => v,
            _ => return PropertyAccessResult::UnsupportedType,
        };
        PropertyAccessResult::Set
    }
    fn begin_list_uint(&mut self, name: &str, _len: usize) -> BeginList<'_, u32> {
        if index_list(name) {
            BeginList::Fill(&mut self.0)
        } else {
            BeginList::UseSetter
        }
    }
}

fn scalar_bytes(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest bytes a binary element of `def` takes (a list at least its
/// count).
fn min_element_bytes(def: &ElementDef) -> u64 {
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) => scalar_bytes(t),
            PropertyType::List(count, _) => scalar_bytes(count),
        })
        .sum()
}

/// The parser's message on one line, its tabs and breaks as spaces.
fn bad(path: &Path, e: impl std::fmt::Display) -> Error {
    let m = e.to_string();
    let m = m.split_whitespace().collect::<Vec<_>>().join(" ");
    Error::file(path, format!("not a readable PLY mesh: {m}"))
}

/// The header of the PLY file at `path`, the reader past it, and checks
/// that make the data readable: a `vertex` element with `x y z`, a `face`
/// element with an index list, and (binary files) at least as many bytes
/// as the header announces.
fn header(path: &Path) -> Result<(Header, Reader<BufReader<std::fs::File>>)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut reader = Reader::new(BufReader::new(file));
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|e| bad(path, e))?;
    let vertex = header
        .elements
        .get("vertex")
        .ok_or_else(|| Error::file(path, "the PLY file has no 'vertex' element"))?;
    for axis in ["x", "y", "z"] {
        match vertex.properties.get(axis).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(Error::file(
                    path,
                    format!("the PLY vertex property '{axis}' is a list, not a number"),
                ))
            }
            None => {
                return Err(Error::file(
                    path,
                    format!("the PLY vertices have no '{axis}' property"),
                ))
            }
        }
    }
    let face = header.elements.get("face").ok_or_else(|| {
        Error::file(
            path,
            "the PLY file has no 'face' element (a point cloud is not a mesh)",
        )
    })?;
    match face
        .properties
        .values()
        .find(|p| index_list(&p.name))
        .map(|p| &p.data_type)
    {
        Some(PropertyType::List(_, t)) if !matches!(t, ScalarType::Float | ScalarType::Double) => {}
        _ => {
            return Err(Error::file(
                path,
                "the PLY faces have no integer list 'vertex_indices' (or 'vertex_index')",
            ))
        }
    }
    if header.encoding != Encoding::Ascii {
        let at = reader
            .get_mut()
            .stream_position()
            .map_err(|e| Error::io(path, e))?;
        let need = header
            .elements
            .values()
            .map(|e| (e.count as u64).saturating_mul(min_element_bytes(e)))
            .fold(at, u64::saturating_add);
        if need > len {
            return Err(Error::file(
                path,
                format!(
                    "truncated: its header announces {} vertices and {} faces, at least {need} bytes, but the file has {len}",
                    vertex.count, face.count
                ),
            ));
        }
    }
    Ok((header, reader))
}

/// Vertices and faces (as triangles) the file's header announces.
pub(super) fn size(path: &Path) -> Result<MeshSize> {
    let (h, _) = header(path)?;
    let count = |name: &str| h.elements.get(name).map_or(0, |e| e.count as u64);
    Ok(MeshSize {
        vertices: count("vertex"),
        triangles: count("face"),
    })
}

/// Reads the mesh (not yet validated: `super::read` does that).
pub(super) fn read(path: &Path) -> Result<TriangleMesh> {
    let (header, mut reader) = header(path)?;
    let mut mesh = TriangleMesh::default();
    let other = Parser::<DefaultElement>::new();
    for (name, def) in &header.elements {
        let what = |e: ply_rs_bw::parser::ParseError| bad(path, format!("element '{name}': {e}"));
        match name.as_str() {
            "vertex" => {
                let v = Parser::<Vertex>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(what)?;
                let has = |names: &[&str]| names.iter().all(|n| def.properties.contains_key(*n));
                let uv_names = [
                    ["s", "t"],
                    ["u", "v"],
                    ["texture_u", "texture_v"],
                    ["texture_s", "texture_t"],
                ];
                let normals = has(&["nx", "ny", "nz"]);
                let uvs = uv_names.iter().any(|n| has(n));
                mesh.positions = v
                    .iter()
                    .map(|Vertex(p)| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
                    .collect();
                if normals {
                    mesh.normals = v
                        .iter()
                        .map(|Vertex(p)| Vec3::new(p[3] as f32, p[4] as f32, p[5] as f32))
                        .collect();
                }
                if uvs {
                    mesh.uvs = v
                        .iter()
                        .map(|Vertex(p)| Vec2::new(p[6] as f32, p[7] as f32))
                        .collect();
                }
            }
            "face" => {
                let faces = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(what)?;
                mesh.triangles.reserve(faces.len());
                for (i, f) in faces.iter().enumerate() {
                    fan(&f.0, i, &mut mesh.triangles).map_err(|m| Error::file(path, m))?;
                }
            }
            _ => {
                other
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(what)?;
            }
        }
    }
    Ok(mesh)
}
