//! Writers for the mesh formats zeroset reads (binary and ASCII STL, OFF, GLB, glTF with an
//! external buffer or a data URI), from indexed triangles, for tests and the format benchmark.
//! Coordinates are written exactly: binary formats as the `f32` bits, text with Rust's shortest
//! round-tripping `f32` formatting.
#![allow(dead_code)]

use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// The corners of triangle `t`.
fn corners(vertices: &[[f32; 3]], t: [u32; 3]) -> [[f32; 3]; 3] {
    t.map(|i| vertices[i as usize])
}

/// A binary STL: header (starting with `header`), count, 50-byte records.
pub fn binary_stl(vertices: &[[f32; 3]], indices: &[[u32; 3]], header: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(84 + 50 * indices.len());
    let mut head = [b' '; 80];
    head[..header.len()].copy_from_slice(header);
    out.extend_from_slice(&head);
    out.extend((indices.len() as u32).to_le_bytes());
    for &t in indices {
        let c = corners(vertices, t);
        out.extend([0u8; 12]);
        for p in c {
            for x in p {
                out.extend(x.to_le_bytes());
            }
        }
        out.extend([0u8; 2]);
    }
    out
}

/// An ASCII STL.
pub fn ascii_stl(vertices: &[[f32; 3]], indices: &[[u32; 3]]) -> Vec<u8> {
    let mut s = String::with_capacity(250 * indices.len() + 32);
    s.push_str("solid zeroset\n");
    for &t in indices {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for p in corners(vertices, t) {
            let _ = writeln!(s, "      vertex {} {} {}", p[0], p[1], p[2]);
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid zeroset\n");
    s.into_bytes()
}

/// An OFF file.
pub fn off(vertices: &[[f32; 3]], indices: &[[u32; 3]]) -> Vec<u8> {
    let mut s = String::with_capacity(40 * (vertices.len() + indices.len()) + 32);
    let _ = writeln!(
        s,
        "OFF\n# written by zeroset's tests\n{} {} 0",
        vertices.len(),
        indices.len()
    );
    for p in vertices {
        let _ = writeln!(s, "{} {} {}", p[0], p[1], p[2]);
    }
    for t in indices {
        let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
    }
    s.into_bytes()
}

/// The glTF JSON and binary buffer of one mesh with one TRIANGLES primitive (u32 indices),
/// `nodes_json` the `nodes` array (the scene lists node 0), `uri` the buffer's URI (`None` in a
/// GLB).
pub fn gltf_parts(
    vertices: &[[f32; 3]],
    indices: &[[u32; 3]],
    nodes_json: &str,
    uri: Option<&str>,
) -> (String, Vec<u8>) {
    let mut bin = Vec::with_capacity(12 * vertices.len() + 12 * indices.len());
    for p in vertices {
        for x in p {
            bin.extend(x.to_le_bytes());
        }
    }
    let vbytes = bin.len();
    for t in indices {
        for i in t {
            bin.extend(i.to_le_bytes());
        }
    }
    let ibytes = bin.len() - vbytes;
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let uri = uri.map_or(String::new(), |u| format!(r#","uri":"{u}""#));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes_json},
"meshes":[{{"name":"shape","primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":4}}]}}],
"buffers":[{{"byteLength":{}{uri}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{vbytes}}},{{"buffer":0,"byteOffset":{vbytes},"byteLength":{ibytes}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}},
{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}]}}"#,
        bin.len(),
        vertices.len(),
        lo[0],
        lo[1],
        lo[2],
        hi[0],
        hi[1],
        hi[2],
        3 * indices.len()
    );
    (json, bin)
}

/// A GLB container of `json` and `bin` (each padded to 4 bytes).
pub fn glb_container(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while b.len() % 4 != 0 {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + if b.is_empty() { 0 } else { 8 + b.len() };
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(0x4E4F_534Au32.to_le_bytes());
    out.extend(j);
    if !b.is_empty() {
        out.extend((b.len() as u32).to_le_bytes());
        out.extend(0x004E_4942u32.to_le_bytes());
        out.extend(b);
    }
    out
}

/// A GLB of the mesh at node 0 with no transform.
pub fn glb(vertices: &[[f32; 3]], indices: &[[u32; 3]]) -> Vec<u8> {
    let (json, bin) = gltf_parts(vertices, indices, r#"[{"mesh":0,"name":"root"}]"#, None);
    glb_container(&json, &bin)
}

/// Writes `bytes` to `path`.
pub fn write(path: &Path, bytes: &[u8]) {
    let mut f = std::fs::File::create(path).unwrap();
    f.write_all(bytes).unwrap();
}
