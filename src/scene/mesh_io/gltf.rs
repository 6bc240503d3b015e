//! glTF 2.0 (`.gltf` JSON with external or `data:` buffers, `.glb` binary): every triangle
//! primitive of the scene's node hierarchy, placed by the nodes' transforms, as one mesh.
//!
//! The `gltf` crate parses and validates the JSON (references between objects); this module
//! splits the GLB container, resolves the buffers and reads the accessors itself, checking every
//! offset and length against the buffer it points into before reading, so a hostile file gives a
//! located error and never an out-of-bounds read or a huge allocation.
//!
//! - **Which nodes**: the default scene's (`scene`), else the first scene's, else every node
//!   without a parent; with a selection (`Mesh(path: …, node: "name")`) only the subtrees of the
//!   nodes of that name, still placed by their parents' transforms.
//! - **Transforms**: each node's `matrix` (column-major) or `translation · rotation · scale`,
//!   converted to `f64` and composed parent · child in `f64` into the `world_from_local` affine
//!   map that a scene's `transform: (matrix: …)` is; positions are mapped in `f64` and rounded to
//!   `f32` once (an identity placement leaves them bit-identical). Normals are mapped by the
//!   inverse transpose. A mirroring placement (negative determinant) reverses the winding, as
//!   glTF specifies, so the geometric normal keeps facing outwards.
//! - **Primitives**: `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` (converted to triangles,
//!   the strip's odd triangles reordered to keep the winding), indexed (`u8`, `u16`, `u32`) or
//!   not. Points and lines are skipped with a note. `POSITION` must be `f32` `VEC3`;
//!   `NORMAL`, when every included primitive has it, is kept as shading normals.
//! - **Refused**: sparse accessors, accessors without a buffer view, quantized positions
//!   (`KHR_mesh_quantization`), compressed meshes and any other extension the file requires.

use super::shared::{check_size, mesh_limit, read_all, reserve};
use super::MeshData;
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::buffer::Source;
use ::gltf::mesh::Mode;
use ::gltf::scene::Transform;
use ::gltf::{Accessor, Document, Node, Semantic};
use glam::{DAffine3, DMat3, DMat4, DQuat, DVec3};
use std::io::Read;
use std::path::Path;

/// A glTF file read: the mesh and notes (skipped primitives) for the load messages.
pub(super) struct Gltf {
    pub data: MeshData,
    pub notes: Vec<String>,
}

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Splits a GLB container into its JSON and optional BIN chunk, checking every length.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    let len = bytes.len();
    if len < 20 {
        return Err(format!(
            "GLB: {len} bytes, shorter than the 12-byte header and a chunk header (truncated?)"
        ));
    }
    let version = u32_at(bytes, 4);
    if version != 2 {
        return Err(format!("GLB: byte 4: version {version} (only glTF 2 is supported)"));
    }
    let total = u32_at(bytes, 8) as usize;
    if total != len {
        return Err(format!(
            "GLB: byte 8: the header says {total} bytes, the file has {len} (truncated, or a wrong length)"
        ));
    }
    let mut at = 12usize;
    let mut chunks: Vec<(u32, &[u8])> = Vec::new();
    while at < len {
        if len - at < 8 {
            return Err(format!(
                "GLB: byte {at}: a chunk header cut off ({} bytes left)",
                len - at
            ));
        }
        let (size, kind) = (u32_at(bytes, at) as usize, u32_at(bytes, at + 4));
        if size > len - at - 8 {
            return Err(format!(
                "GLB: byte {at}: chunk {} claims {size} bytes, {} remain (truncated, or a lying length)",
                chunks.len(),
                len - at - 8
            ));
        }
        chunks.push((kind, &bytes[at + 8..at + 8 + size]));
        at += 8 + size;
    }
    match chunks.as_slice() {
        [(CHUNK_JSON, json), rest @ ..] => {
            let bin = rest.iter().find(|(k, _)| *k == CHUNK_BIN).map(|(_, b)| *b);
            Ok((json, bin))
        }
        _ => Err("GLB: byte 12: the first chunk is not the JSON chunk".into()),
    }
}

/// Decodes standard base64 (padding optional, no whitespace).
fn base64(text: &str) -> Result<Vec<u8>, String> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return None,
        } as u32)
    };
    let text = text.trim_end_matches('=').as_bytes();
    let mut out = Vec::new();
    reserve(&mut out, text.len() as u64 / 4 * 3 + 3, "data URI")?;
    let (mut acc, mut bits) = (0u32, 0);
    for (i, &c) in text.iter().enumerate() {
        let v = value(c).ok_or_else(|| format!("character {i} (`{}`) is not base64", c as char))?;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// `%XX` escapes of a relative URI decoded.
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() && b[i + 1].is_ascii_hexdigit() && b[i + 2].is_ascii_hexdigit() {
            let hex = |c: u8| (c as char).to_digit(16).unwrap_or(0) as u8;
            out.push(hex(b[i + 1]) * 16 + hex(b[i + 2]));
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The bytes of each buffer, at least its declared `byteLength` long.
fn load_buffers(path: &Path, doc: &Document, blob: Option<&[u8]>) -> Result<Vec<Vec<u8>>, String> {
    let mut total = 0u64;
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let i = buffer.index();
        let want = buffer.length() as u64;
        total = total.saturating_add(want);
        check_size(total).map_err(|e| format!("buffers[{i}]: the buffers total {e}"))?;
        let bytes = match buffer.source() {
            Source::Bin => {
                let blob =
                    blob.ok_or_else(|| format!("buffers[{i}]: refers to the GLB's BIN chunk, which is missing"))?;
                if (blob.len() as u64) < want {
                    return Err(format!(
                        "buffers[{i}]: byteLength {want}, the BIN chunk has {} bytes (truncated?)",
                        blob.len()
                    ));
                }
                blob[..want as usize].to_vec()
            }
            Source::Uri(uri) if uri.starts_with("data:") => {
                let (head, payload) = uri
                    .split_once(',')
                    .ok_or_else(|| format!("buffers[{i}]: data URI without a `,`"))?;
                if !head.ends_with(";base64") {
                    return Err(format!("buffers[{i}]: data URI `{head}` is not base64"));
                }
                check_size(payload.len() as u64 / 4 * 3).map_err(|e| format!("buffers[{i}]: data URI of {e}"))?;
                let bytes = base64(payload).map_err(|e| format!("buffers[{i}]: data URI: {e}"))?;
                if (bytes.len() as u64) < want {
                    return Err(format!(
                        "buffers[{i}]: byteLength {want}, the data URI holds {} bytes",
                        bytes.len()
                    ));
                }
                bytes
            }
            Source::Uri(uri) => {
                if uri.contains("://") {
                    return Err(format!(
                        "buffers[{i}]: `{uri}`: only relative file paths and data URIs are read"
                    ));
                }
                let file = path.parent().unwrap_or(Path::new("")).join(percent_decode(uri));
                // a regular file within the limit, checked before it is opened (never a FIFO)
                let have = crate::resources::check_input_path(&file, "glTF buffer", mesh_limit()?, "mesh files")
                    .map_err(|e| format!("buffers[{i}]: {}: {e}", file.display()))?;
                if have < want {
                    return Err(format!(
                        "buffers[{i}]: {}: byteLength {want}, the file has {have} bytes (truncated?)",
                        file.display()
                    ));
                }
                let mut bytes = Vec::new();
                reserve(&mut bytes, want, &format!("buffers[{i}]"))?;
                std::fs::File::open(&file)
                    .and_then(|f| f.take(want).read_to_end(&mut bytes))
                    .map_err(|e| format!("buffers[{i}]: {}: {e}", file.display()))?;
                if (bytes.len() as u64) < want {
                    return Err(format!(
                        "buffers[{i}]: {}: shorter than byteLength {want}",
                        file.display()
                    ));
                }
                bytes
            }
        };
        out.push(bytes);
    }
    Ok(out)
}

/// The element size of a data type.
fn component_size(t: DataType) -> u64 {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

/// An accessor's elements as byte slices, every bound checked: `(bytes, stride, elem_size)`.
fn accessor_bytes<'b>(a: &Accessor, buffers: &'b [Vec<u8>], what: &str) -> Result<(&'b [u8], usize, usize), String> {
    let i = a.index();
    let place = format!("accessors[{i}] ({what})");
    if a.sparse().is_some() {
        return Err(format!("{place}: sparse accessors are not supported"));
    }
    let view = a
        .view()
        .ok_or_else(|| format!("{place}: no bufferView (all-zero accessors are not supported)"))?;
    let elem = component_size(a.data_type()) * a.dimensions().multiplicity() as u64;
    let stride = view.stride().map_or(elem, |s| s as u64);
    if stride < elem {
        return Err(format!(
            "{place}: byteStride {stride} is smaller than an element ({elem} bytes)"
        ));
    }
    let buffer = &buffers[view.buffer().index()];
    let (view_offset, view_len) = (view.offset() as u64, view.length() as u64);
    if view_offset + view_len > buffer.len() as u64 {
        return Err(format!(
            "{place}: bufferViews[{}] spans bytes {view_offset}..{} of buffers[{}], which has {} bytes",
            view.index(),
            view_offset + view_len,
            view.buffer().index(),
            buffer.len()
        ));
    }
    let count = a.count() as u64;
    if count == 0 {
        return Err(format!("{place}: count is 0"));
    }
    let need = (a.offset() as u64)
        .saturating_add((count - 1).saturating_mul(stride))
        .saturating_add(elem);
    if need > view_len {
        return Err(format!(
            "{place}: {count} elements of {elem} bytes (stride {stride}, offset {}) need {need} bytes, \
             bufferViews[{}] has {view_len} (a lying count, or a short buffer)",
            a.offset(),
            view.index()
        ));
    }
    let start = (view_offset + a.offset() as u64) as usize;
    Ok((
        &buffer[start..start + need as usize - a.offset()],
        stride as usize,
        elem as usize,
    ))
}

/// Reads a `VEC3` `f32` accessor (positions, normals), every value finite.
fn read_vec3(a: &Accessor, buffers: &[Vec<u8>], what: &str) -> Result<Vec<[f32; 3]>, String> {
    if a.dimensions() != Dimensions::Vec3 || a.data_type() != DataType::F32 {
        return Err(format!(
            "accessors[{}] ({what}): {:?} {:?}, expected VEC3 of FLOAT (quantized attributes, \
             KHR_mesh_quantization, are not supported)",
            a.index(),
            a.dimensions(),
            a.data_type()
        ));
    }
    let (bytes, stride, _) = accessor_bytes(a, buffers, what)?;
    let mut out = Vec::new();
    reserve(&mut out, a.count() as u64, what)?;
    for k in 0..a.count() {
        let b = &bytes[k * stride..];
        let p: [f32; 3] =
            std::array::from_fn(|c| f32::from_le_bytes([b[4 * c], b[4 * c + 1], b[4 * c + 2], b[4 * c + 3]]));
        if !p.iter().all(|x| x.is_finite()) {
            return Err(format!(
                "accessors[{}] ({what}): element {k}: {p:?} is not finite",
                a.index()
            ));
        }
        out.push(p);
    }
    Ok(out)
}

/// Reads a `SCALAR` unsigned index accessor.
fn read_indices(a: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    if a.dimensions() != Dimensions::Scalar || !matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32) {
        return Err(format!(
            "accessors[{}] (indices): {:?} {:?}, expected SCALAR of an unsigned integer type",
            a.index(),
            a.dimensions(),
            a.data_type()
        ));
    }
    let (bytes, stride, _) = accessor_bytes(a, buffers, "indices")?;
    let mut out = Vec::new();
    reserve(&mut out, a.count() as u64, "indices")?;
    for k in 0..a.count() {
        let b = &bytes[k * stride..];
        out.push(match a.data_type() {
            DataType::U8 => u32::from(b[0]),
            DataType::U16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        });
    }
    Ok(out)
}

/// A node's local transform in `f64` (`world_from_local` convention).
fn local(node: &Node) -> DAffine3 {
    match node.transform() {
        Transform::Matrix { matrix } => {
            let m = DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from)));
            DAffine3::from_mat4(m)
        }
        Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let q = DQuat::from_array(rotation.map(f64::from));
            let q = if q.length_squared() > 0.0 {
                q.normalize()
            } else {
                DQuat::IDENTITY
            };
            DAffine3::from_scale_rotation_translation(
                DVec3::from_array(scale.map(f64::from)),
                q,
                DVec3::from_array(translation.map(f64::from)),
            )
        }
    }
}

/// Reads a glTF or GLB file; `node` selects the subtrees of the nodes of that name.
pub(super) fn read_gltf(path: &Path, node: Option<&str>) -> Result<Gltf, String> {
    let bytes = read_all(path)?;
    let (json, blob) = if bytes.starts_with(GLB_MAGIC) {
        split_glb(&bytes)?
    } else {
        (bytes.as_slice(), None)
    };
    let root: ::gltf::json::Root =
        ::gltf::json::deserialize::from_slice(json).map_err(|e| format!("glTF JSON: {e}"))?;
    let doc = Document::from_json(root).map_err(|e| match e {
        ::gltf::Error::Validation(list) => {
            let shown: Vec<String> = list.iter().take(3).map(|(p, e)| format!("{p}: {e}")).collect();
            format!("glTF: invalid: {}", shown.join("; "))
        }
        e => format!("glTF: {e}"),
    })?;
    if let Some(ext) = doc.extensions_required().next() {
        let why = match ext {
            "KHR_mesh_quantization" => " (quantized attributes are not supported; export with float positions)",
            "KHR_draco_mesh_compression" | "EXT_meshopt_compression" => " (compressed meshes are not supported)",
            _ => "",
        };
        return Err(format!("glTF: requires the extension `{ext}`, not supported{why}"));
    }
    let buffers = load_buffers(path, &doc, blob)?;

    // the root nodes to walk, with their parents' placement
    let nodes: Vec<Node> = doc.nodes().collect();
    let mut parent = vec![None; nodes.len()];
    for n in &nodes {
        for c in n.children() {
            if parent[c.index()].is_some() || c.index() == n.index() {
                return Err(format!(
                    "glTF: nodes[{}] has more than one parent (the hierarchy must be a tree)",
                    c.index()
                ));
            }
            parent[c.index()] = Some(n.index());
        }
    }
    let world_of = |mut i: usize| -> Result<DAffine3, String> {
        let mut m = local(&nodes[i]);
        let mut steps = 0;
        while let Some(p) = parent[i] {
            m = local(&nodes[p]) * m;
            i = p;
            steps += 1;
            if steps > nodes.len() {
                return Err(format!("glTF: nodes[{i}]: the hierarchy has a cycle"));
            }
        }
        Ok(m)
    };
    let roots: Vec<(usize, DAffine3)> = match node {
        Some(name) => {
            let picked: Vec<usize> = nodes
                .iter()
                .filter(|n| n.name() == Some(name))
                .map(Node::index)
                .collect();
            if picked.is_empty() {
                let names: Vec<&str> = nodes.iter().filter_map(Node::name).take(20).collect();
                return Err(format!("glTF: no node named {name:?} (nodes: {names:?})"));
            }
            picked
                .into_iter()
                .map(|i| Ok((i, world_of(i)?)))
                .collect::<Result<_, String>>()?
        }
        None => {
            let scene = doc.default_scene().or_else(|| doc.scenes().next());
            let ids: Vec<usize> = match scene {
                Some(s) => s.nodes().map(|n| n.index()).collect(),
                None => (0..nodes.len()).filter(|&i| parent[i].is_none()).collect(),
            };
            ids.into_iter().map(|i| (i, local(&nodes[i]))).collect()
        }
    };

    let mut data = MeshData::default();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    let mut all_normals = true;
    let mut notes = Vec::new();
    let mut skipped = 0usize;
    let mut stack = roots;
    let mut visits = 0usize;
    while let Some((i, world)) = stack.pop() {
        visits += 1;
        if visits > nodes.len() * 2 + 1 {
            return Err("glTF: the node hierarchy has a cycle".into());
        }
        let n = &nodes[i];
        for c in n.children() {
            stack.push((c.index(), world * local(&c)));
        }
        let Some(mesh) = n.mesh() else { continue };
        let linear = world.matrix3;
        let det = linear.determinant();
        let identity = world == DAffine3::IDENTITY;
        let normal_map = if det != 0.0 {
            linear.inverse().transpose()
        } else {
            DMat3::ZERO
        };
        for prim in mesh.primitives() {
            let place = format!("meshes[{}].primitives[{}] (nodes[{i}])", mesh.index(), prim.index());
            let mode = prim.mode();
            if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                skipped += 1;
                notes.push(format!("{place}: {mode:?} skipped (only triangles are ray cast)"));
                continue;
            }
            let pos = prim
                .get(&Semantic::Positions)
                .ok_or_else(|| format!("glTF: {place}: no POSITION attribute"))?;
            let positions = read_vec3(&pos, &buffers, "POSITION").map_err(|e| format!("glTF: {place}: {e}"))?;
            let nv = positions.len();
            let list: Vec<u32> = match prim.indices() {
                Some(a) => read_indices(&a, &buffers).map_err(|e| format!("glTF: {place}: {e}"))?,
                None => (0..nv as u32).collect(),
            };
            if let Some(bad) = list.iter().position(|&k| k as usize >= nv) {
                return Err(format!(
                    "glTF: {place}: index {bad} is {}, out of range ({nv} positions)",
                    list[bad]
                ));
            }
            let tris: Vec<[u32; 3]> = match mode {
                Mode::Triangles => list.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
                Mode::TriangleStrip => (0..list.len().saturating_sub(2))
                    .map(|k| {
                        if k % 2 == 0 {
                            [list[k], list[k + 1], list[k + 2]]
                        } else {
                            [list[k + 1], list[k], list[k + 2]]
                        }
                    })
                    .collect(),
                _ => (1..list.len().saturating_sub(1))
                    .map(|k| [list[0], list[k], list[k + 1]])
                    .collect(),
            };
            if tris.is_empty() {
                skipped += 1;
                notes.push(format!("{place}: no triangles, skipped"));
                continue;
            }
            let base = data.vertices.len() as u64;
            if base + nv as u64 >= u64::from(u32::MAX) {
                return Err(format!("glTF: {place}: more than 2³² − 2 vertices in all"));
            }
            let base = base as u32;
            reserve(&mut data.vertices, nv as u64, "vertices")?;
            if identity {
                data.vertices.extend_from_slice(&positions);
            } else {
                data.vertices.extend(positions.iter().map(|p| {
                    let q = world.transform_point3(DVec3::from_array(p.map(f64::from)));
                    [q.x as f32, q.y as f32, q.z as f32]
                }));
            }
            reserve(&mut data.indices, tris.len() as u64, "triangles")?;
            data.indices.extend(tris.iter().map(|t| {
                let t = t.map(|k| k + base);
                if det < 0.0 {
                    [t[0], t[2], t[1]]
                } else {
                    t
                }
            }));
            match prim.get(&Semantic::Normals) {
                Some(a) if all_normals => {
                    let ns = read_vec3(&a, &buffers, "NORMAL").map_err(|e| format!("glTF: {place}: {e}"))?;
                    if ns.len() != nv {
                        return Err(format!("glTF: {place}: {} normals for {nv} positions", ns.len()));
                    }
                    if identity {
                        normals.extend_from_slice(&ns);
                    } else {
                        normals.extend(ns.iter().map(|v| {
                            let m = normal_map * DVec3::from_array(v.map(f64::from));
                            [m.x as f32, m.y as f32, m.z as f32]
                        }));
                    }
                }
                _ => all_normals = false,
            }
        }
    }
    if data.indices.is_empty() {
        return Err(format!(
            "glTF: no triangles{} ({skipped} primitives skipped)",
            node.map_or(String::new(), |n| format!(" under the node {n:?}"))
        ));
    }
    if all_normals && !normals.is_empty() && normals.iter().all(|n| n.iter().any(|&x| x != 0.0)) {
        data.normals = Some(normals);
    }
    Ok(Gltf { data, notes })
}
