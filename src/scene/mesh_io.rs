//! Mesh files: OBJ (via `tobj`) and PLY (ASCII, binary little- and big-endian, via `ply-rs-bw`),
//! and the scene description `Mesh(path: "meshes/x.ply", normals: true)`.
//!
//! Polygons are fanned into triangles (`tobj` triangulates OBJ faces; PLY faces of `n > 3`
//! vertices become `n − 2` triangles `(0, i, i + 1)`), so a triangle's index (the `feature` of a
//! hit) is its position in the file's faces after fanning. OBJ files are loaded with one index per
//! vertex (`tobj`'s `single_index`), all objects of the file merged into one mesh. Per-vertex
//! normals are read from OBJ `vn` records and from PLY `nx, ny, nz` vertex properties.
//!
//! Binary PLY payloads are decoded by the `ply_binary` submodule from one in-memory buffer; ASCII ones go
//! through ply-rs-bw's per-property reader ([`read_ply_generic`]). Both give the same data.
//!
//! Every error names the file, and the element, line or face where the format gives one.
//!
//! STL (binary, ASCII), OFF and glTF / GLB are read by the `stl`, `stl_ascii`, `off` and `gltf`
//! submodules, chosen in `formats` ([`read_mesh_report`]); see `docs/mesh-formats.md`. The text
//! formats share `text` (blocks of lines, parallel pieces, number parsing), STL corners are
//! welded by `weld`, and `reference` keeps the former line-by-line readers as the tests' oracle.

mod formats;
mod gltf;
mod off;
mod ply_binary;
#[cfg(test)]
mod reference;
mod shared;
mod stl;
mod stl_ascii;
mod text;
mod weld;

pub use formats::{read_mesh_report, MeshReport};
pub use shared::{MAX_LINE_BYTES, MAX_MESH_FILE_BYTES};

use crate::scene::shape_desc::{BuildContext, SceneShape};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{Encoding, Header, Property, PropertyAccess};
use serde::Deserialize;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zeroset_primitives::{Mesh, Primitive, PrimitiveError};

/// A mesh file could not be loaded.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct MeshIoError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong, with the element, line or face where known.
    pub message: String,
}

fn error(path: &Path, message: impl Into<String>) -> MeshIoError {
    MeshIoError {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// The arrays of a mesh file, before validation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Positions.
    pub vertices: Vec<[f32; 3]>,
    /// Triangles (counter-clockwise index triples).
    pub indices: Vec<[u32; 3]>,
    /// Per-vertex normals, if the file has them.
    pub normals: Option<Vec<[f32; 3]>>,
}

impl MeshData {
    /// Validates and builds the [`Mesh`] (BVH included); errors name `path`.
    pub fn into_mesh(self, path: &Path, normals: bool) -> Result<Mesh, MeshIoError> {
        let n = if normals { self.normals } else { None };
        Mesh::new(self.vertices, self.indices, n).map_err(|e| error(path, format!("{}: {}", e.field, e.problem)))
    }
}

/// Reads `path` by its content or extension (`.obj`, `.ply`, `.stl`, `.off`, `.gltf`, `.glb`,
/// any case; see [`read_mesh_report`]).
pub fn read_mesh(path: &Path) -> Result<MeshData, MeshIoError> {
    read_mesh_report(path, None).map(|r| r.data)
}

/// Reads and builds a mesh file (see [`read_mesh`], [`MeshData::into_mesh`]).
pub fn load_mesh(path: &Path, normals: bool) -> Result<Mesh, MeshIoError> {
    read_mesh(path)?.into_mesh(path, normals)
}

/// Reads an OBJ file (all objects merged; faces triangulated).
pub fn read_obj(path: &Path) -> Result<MeshData, MeshIoError> {
    if let Err(e) = std::fs::metadata(path) {
        return Err(error(path, e.to_string()));
    }
    let (models, _) = tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS).map_err(|e| error(path, e.to_string()))?;
    let mut data = MeshData::default();
    let mut normals = Vec::new();
    let mut all_have_normals = true;
    for model in &models {
        let m = &model.mesh;
        let base = data.vertices.len() as u32;
        let count = m.positions.len() / 3;
        data.vertices
            .extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        if m.normals.len() == m.positions.len() {
            normals.extend(m.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
        } else {
            all_have_normals = false;
        }
        for (face, t) in m.indices.chunks_exact(3).enumerate() {
            if let Some(&bad) = t.iter().find(|&&i| i as usize >= count) {
                return Err(error(
                    path,
                    format!(
                        "object {:?}, triangle {face}: vertex index {bad} out of range ({count} vertices)",
                        model.name
                    ),
                ));
            }
            data.indices.push([base + t[0], base + t[1], base + t[2]]);
        }
    }
    if all_have_normals && !normals.is_empty() {
        data.normals = Some(normals);
    }
    Ok(data)
}

/// A PLY vertex: position and optional normal (float or double).
struct PlyVertex {
    p: [f32; 3],
    n: [f32; 3],
    has_normal: u8,
}

fn scalar(p: &Property) -> Option<f32> {
    Some(match *p {
        Property::Float(x) => x,
        Property::Double(x) => x as f32,
        Property::Char(x) => f32::from(x),
        Property::UChar(x) => f32::from(x),
        Property::Short(x) => f32::from(x),
        Property::UShort(x) => f32::from(x),
        Property::Int(x) => x as f32,
        Property::UInt(x) => x as f32,
        _ => return None,
    })
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        Self {
            p: [f32::NAN; 3],
            n: [0.0; 3],
            has_normal: 0,
        }
    }

    fn set_property(&mut self, name: &str, property: Property) {
        let Some(x) = scalar(&property) else { return };
        match name {
            "x" => self.p[0] = x,
            "y" => self.p[1] = x,
            "z" => self.p[2] = x,
            "nx" => (self.n[0], self.has_normal) = (x, self.has_normal | 1),
            "ny" => (self.n[1], self.has_normal) = (x, self.has_normal | 2),
            "nz" => (self.n[2], self.has_normal) = (x, self.has_normal | 4),
            _ => {}
        }
    }
}

/// A PLY face: its vertex index list (any integer type), `None` entries negative.
#[derive(Default)]
struct PlyFace {
    indices: Vec<i64>,
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: &str, property: Property) {
        if name != "vertex_indices" && name != "vertex_index" {
            return;
        }
        self.indices = match property {
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            _ => return,
        };
    }
}

/// Any other element, read and dropped.
struct Ignored;

impl PropertyAccess for Ignored {
    fn new() -> Self {
        Self
    }
}

/// Reads a PLY file: `vertex` (`x, y, z`, optional `nx, ny, nz`) and `face` (`vertex_indices`)
/// elements; other elements and properties are skipped. Binary payloads are decoded in memory
/// (`ply_binary`), ASCII ones by ply-rs-bw.
pub fn read_ply(path: &Path) -> Result<MeshData, MeshIoError> {
    let (mut reader, header) = read_ply_header(path)?;
    if header.encoding == Encoding::Ascii {
        return read_ply_payload(path, &mut reader, &header);
    }
    // an upper bound of the payload's length, to reserve the buffer once
    let size = reader.get_ref().metadata().map_or(0, |m| m.len());
    ply_binary::read_payload(&mut reader, size, &header).map_err(|message| error(path, message))
}

/// Reads a PLY file as [`read_ply`] does, but always through ply-rs-bw's per-property payload
/// reader (the ASCII path), to check the binary decoder against.
#[doc(hidden)]
pub fn read_ply_generic(path: &Path) -> Result<MeshData, MeshIoError> {
    let (mut reader, header) = read_ply_header(path)?;
    read_ply_payload(path, &mut reader, &header)
}

/// Opens a PLY file and reads its header; the reader is left at the payload.
fn read_ply_header(path: &Path) -> Result<(BufReader<std::fs::File>, Header), MeshIoError> {
    let file = std::fs::File::open(path).map_err(|e| error(path, e.to_string()))?;
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let header = Parser::<Ignored>::new()
        .read_header(&mut reader)
        .map_err(|e| error(path, format!("header: {e}")))?;
    Ok((reader, header))
}

/// The message for a vertex whose position is not finite.
fn vertex_not_finite(i: usize, p: [f32; 3]) -> String {
    format!("vertex {i}: position {p:?} is not finite (or x, y, z missing)")
}

/// The message for a face of fewer than 3 vertices.
fn face_too_few_indices(f: usize, n: usize) -> String {
    format!("face {f}: {n} vertex indices (at least 3 needed)")
}

/// The message for a face index outside `0..nv`.
fn face_index_out_of_range(f: usize, bad: i64, nv: usize) -> String {
    format!("face {f}: vertex index {bad} out of range ({nv} vertices)")
}

/// Reads the payload through ply-rs-bw's per-property callbacks ([`PlyVertex`], [`PlyFace`]).
fn read_ply_payload(
    path: &Path,
    reader: &mut BufReader<std::fs::File>,
    header: &Header,
) -> Result<MeshData, MeshIoError> {
    let mut vertices: Option<Vec<PlyVertex>> = None;
    let mut faces: Option<Vec<PlyFace>> = None;
    for (name, element) in &header.elements {
        let result = match name.as_str() {
            "vertex" => Parser::<PlyVertex>::new()
                .read_payload_for_element(reader, element, header)
                .map(|v| vertices = Some(v)),
            "face" => Parser::<PlyFace>::new()
                .read_payload_for_element(reader, element, header)
                .map(|f| faces = Some(f)),
            _ => Parser::<Ignored>::new()
                .read_payload_for_element(reader, element, header)
                .map(|_| ()),
        };
        if let Err(e) = result {
            let at_end = reader.fill_buf().is_ok_and(|b| b.is_empty());
            let truncated = if at_end {
                "unexpected end of file (truncated?): "
            } else {
                ""
            };
            return Err(error(
                path,
                format!("element `{name}` ({} expected): {truncated}{e}", element.count),
            ));
        }
    }
    let vertices = vertices.ok_or_else(|| error(path, "no `vertex` element"))?;
    let faces = faces.ok_or_else(|| error(path, "no `face` element"))?;
    let nv = vertices.len();
    let mut data = MeshData {
        vertices: Vec::with_capacity(nv),
        indices: Vec::with_capacity(faces.len()),
        normals: None,
    };
    for (i, v) in vertices.iter().enumerate() {
        if !v.p.iter().all(|x| x.is_finite()) {
            return Err(error(path, vertex_not_finite(i, v.p)));
        }
        data.vertices.push(v.p);
    }
    if vertices.iter().all(|v| v.has_normal == 7) {
        data.normals = Some(vertices.iter().map(|v| v.n).collect());
    }
    for (f, face) in faces.iter().enumerate() {
        if face.indices.len() < 3 {
            return Err(error(path, face_too_few_indices(f, face.indices.len())));
        }
        if let Some(&bad) = face.indices.iter().find(|&&i| i < 0 || i as usize >= nv) {
            return Err(error(path, face_index_out_of_range(f, bad, nv)));
        }
        let idx = |k: usize| face.indices[k] as u32;
        for k in 1..face.indices.len() - 1 {
            data.indices.push([idx(0), idx(k), idx(k + 1)]);
        }
    }
    Ok(data)
}

fn yes() -> bool {
    true
}

/// The warning for a mesh with degenerate (zero-area) triangles, after the mesh's name: all of
/// them (the mesh has no surface, [`Mesh::has_surface`]) or some; `None` when there are none.
/// Scene files and Python's `Scene.add_mesh` both give it.
#[must_use]
pub fn degenerate_warning(mesh: &Mesh) -> Option<String> {
    let (skipped, count) = (mesh.skipped_triangles(), mesh.triangle_count());
    if !mesh.has_surface() {
        Some(format!(
            "all {count} triangles are degenerate (zero area): the mesh has no surface and is never hit"
        ))
    } else if skipped > 0 {
        Some(format!(
            "{skipped} of {count} triangles are degenerate (zero area) and are never hit"
        ))
    } else {
        None
    }
}

/// `Mesh(path: "meshes/bunny.ply", normals: true)`: a triangle mesh from an OBJ or PLY file, the
/// path relative to the scene file. Objects naming the same file (and `normals` setting) share
/// one loaded mesh; place copies with each object's `transform`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Mesh")]
pub struct MeshDesc {
    /// The mesh file (`.obj`, `.ply`, `.stl`, `.off`, `.gltf`, `.glb`), relative to the scene
    /// file's directory.
    pub path: PathBuf,
    /// Use the file's per-vertex normals as shading normals (the `ShadingNormal` AOV); default
    /// true. The `Normal` AOV is always the geometric normal.
    #[serde(default = "yes")]
    pub normals: bool,
    /// glTF only: the nodes of this name (and their children), placed by their parents'
    /// transforms; default the whole scene.
    #[serde(default)]
    pub node: Option<String>,
}

impl SceneShape for MeshDesc {
    fn build(&self, context: &BuildContext) -> Result<Arc<dyn Primitive>, PrimitiveError> {
        let path = context.resolve(&self.path);
        let mut key = if self.normals {
            path.clone()
        } else {
            PathBuf::from(format!("{}#no-normals", path.display()))
        };
        if let Some(node) = &self.node {
            key = PathBuf::from(format!("{}#node={node}", key.display()));
        }
        let mut loaded = context.loaded.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(mesh) = loaded.get(&key) {
            return Ok(Arc::clone(mesh));
        }
        let report = read_mesh_report(&path, self.node.as_deref())
            .map_err(|e| PrimitiveError::new("Mesh", "path", e.to_string()))?;
        for note in &report.notes {
            context.warn(format!("{}: {note}", path.display()));
        }
        let mesh = report
            .data
            .into_mesh(&path, self.normals)
            .map_err(|e| PrimitiveError::new("Mesh", "path", e.to_string()))?;
        if let Some(warning) = degenerate_warning(&mesh) {
            context.warn(format!("{}: {warning}", path.display()));
        }
        let mesh: Arc<dyn Primitive> = Arc::new(mesh);
        loaded.insert(key, Arc::clone(&mesh));
        Ok(mesh)
    }
}
