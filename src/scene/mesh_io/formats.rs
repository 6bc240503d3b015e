//! Choosing a reader: by the file's content where it has a magic number (`glTF` for GLB, `ply`
//! for PLY) and otherwise by its extension (any case): `.obj`, `.ply`, `.stl`, `.off`, `.gltf`,
//! `.glb`. STL decides binary against ASCII by content itself (see [`super::stl`]).

use super::{error, gltf, off, read_obj, read_ply, stl, MeshData, MeshIoError};
use std::io::Read;
use std::path::Path;

/// A mesh file read, with notes for the load messages (vertices welded, primitives skipped).
#[derive(Clone, Debug, Default)]
pub struct MeshReport {
    /// The arrays read.
    pub data: MeshData,
    /// What the reader reports beside the arrays, one line each, without the path.
    pub notes: Vec<String>,
    /// For STL: corners merged into an earlier, equal vertex by welding (0 for other formats).
    pub merged_vertices: u64,
}

/// The mesh file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Obj,
    Ply,
    Stl,
    Off,
    Gltf,
}

/// The format from the first bytes, where they are a magic number.
fn by_content(path: &Path) -> Option<Format> {
    let mut head = [0u8; 5];
    let mut file = std::fs::File::open(path).ok()?;
    let mut got = 0;
    while got < head.len() {
        match file.read(&mut head[got..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => got += n,
        }
    }
    let head = &head[..got];
    if head.starts_with(b"glTF") {
        Some(Format::Gltf)
    } else if head.starts_with(b"ply\n") || head.starts_with(b"ply\r") {
        Some(Format::Ply)
    } else {
        None
    }
}

fn by_extension(path: &Path) -> Option<Format> {
    let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
    Some(match ext.as_str() {
        "obj" => Format::Obj,
        "ply" => Format::Ply,
        "stl" => Format::Stl,
        "off" => Format::Off,
        "gltf" | "glb" => Format::Gltf,
        _ => return None,
    })
}

/// Reads a mesh file of any supported format (see the module documentation), `node` selecting
/// the glTF nodes of that name (an error for other formats).
pub fn read_mesh_report(path: &Path, node: Option<&str>) -> Result<MeshReport, MeshIoError> {
    // a regular file within the limit, checked before anything opens it (a FIFO would block the
    // open, a device never end); a missing file is said below, as before
    if std::fs::metadata(path).is_ok() {
        super::shared::file_len(path).map_err(|m| error(path, m))?;
    }
    let Some(format) = by_content(path).or_else(|| by_extension(path)) else {
        if let Err(e) = std::fs::metadata(path) {
            return Err(error(path, e.to_string()));
        }
        return Err(error(
            path,
            "unknown mesh format (expected a .obj, .ply, .stl, .off, .gltf or .glb file)",
        ));
    };
    if node.is_some() && format != Format::Gltf {
        return Err(error(path, "`node` selects glTF nodes; this is not a glTF file"));
    }
    let mut report = MeshReport::default();
    match format {
        Format::Obj => report.data = read_obj(path)?,
        Format::Ply => report.data = read_ply(path)?,
        Format::Off => report.data = off::read_off(path).map_err(|m| error(path, m))?,
        Format::Stl => {
            let stl = stl::read_stl(path).map_err(|m| error(path, m))?;
            report.notes.push(format!(
                "STL ({}): {} triangle corners welded into {} vertices ({} merged)",
                if stl.ascii { "ASCII" } else { "binary" },
                stl.corners,
                stl.data.vertices.len(),
                stl.merged
            ));
            report.merged_vertices = stl.merged;
            report.data = stl.data;
        }
        Format::Gltf => {
            let gltf = gltf::read_gltf(path, node).map_err(|m| error(path, m))?;
            report.notes = gltf.notes;
            report.data = gltf.data;
        }
    }
    Ok(report)
}
