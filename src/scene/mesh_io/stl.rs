//! STL, binary and ASCII, read directly (streamed), corners welded exactly into shared vertices.
//!
//! Binary: an 80-byte header, a little-endian `u32` triangle count `n`, then `n` records of
//! 50 bytes (normal, three corners as `f32` triples, a 2-byte attribute), so the file is exactly
//! `84 + 50·n` bytes. ASCII: `solid name`, facets of `facet normal …` / `outer loop` /
//! three `vertex x y z` / `endloop` / `endfacet`, then `endsolid` (several solids in one file are
//! read as one mesh). Facet normals are ignored (the geometric normal comes from the winding).
//!
//! Which of the two: a file not starting with `solid` is binary. One that does is binary when
//! its size is exactly `84 + 50·n` for the count at byte 80 and it parses as binary (an exporter
//! may write `solid` into a binary header); otherwise it is read as ASCII.
//!
//! Corners are welded with [`Welder`]: equal positions (bit-equal, and `-0.0` with `0.0`) become
//! one vertex, so a closed STL is as watertight as the indexed mesh it was written from.
//!
//! A binary file is read in blocks of records, the next block read and decoded while the
//! current one is welded; an ASCII one is read by `stl_ascii`.

use super::shared::{file_len, reserve};
use super::stl_ascii::read_ascii;
use super::weld::{Corner, Welder};
use super::MeshData;
use std::io::Read;
use std::path::Path;

/// An STL file read and welded; `merged` counts the corners merged into earlier vertices.
pub(super) struct Stl {
    pub data: MeshData,
    pub corners: u64,
    pub merged: u64,
    pub ascii: bool,
}

/// Reads an STL file, binary or ASCII by its content (see the module documentation).
pub(super) fn read_stl(path: &Path) -> Result<Stl, String> {
    let len = file_len(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut head = [0u8; 84];
    let got = read_up_to(&mut file, &mut head)?;
    let starts_solid = head[..got].trim_ascii_start().starts_with(b"solid");
    let count = (got == 84).then(|| u32::from_le_bytes([head[80], head[81], head[82], head[83]]));
    let size_fits = count.is_some_and(|n| 84 + 50 * u64::from(n) == len);
    if starts_solid && !size_fits {
        return read_ascii(path);
    }
    if starts_solid {
        // the size says binary; a parse failure falls back to ASCII (then the binary error is kept)
        return match read_binary(path, len) {
            Ok(stl) => Ok(stl),
            Err(binary) => read_ascii(path).map_err(|_| binary),
        };
    }
    read_binary(path, len)
}

fn read_up_to(file: &mut std::fs::File, buf: &mut [u8]) -> Result<usize, String> {
    let mut got = 0;
    while got < buf.len() {
        match file.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.to_string()),
        }
    }
    Ok(got)
}

/// Triangles per block of a binary STL read.
const BLOCK_TRIANGLES: usize = 1 << 14;

/// Reads a binary STL of `len` bytes.
fn read_binary(path: &Path, len: u64) -> Result<Stl, String> {
    read_binary_blocks(path, len, BLOCK_TRIANGLES)
}

/// Reads a binary STL of `len` bytes in blocks of `block` triangles.
pub(super) fn read_binary_blocks(path: &Path, len: u64, block: usize) -> Result<Stl, String> {
    if len < 84 {
        return Err(format!(
            "binary STL: {len} bytes, shorter than the 84-byte header and count (truncated, or not an STL file?)"
        ));
    }
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut head = [0u8; 84];
    file.read_exact(&mut head).map_err(|e| e.to_string())?;
    let n = u32::from_le_bytes([head[80], head[81], head[82], head[83]]);
    let want = 84 + 50 * u64::from(n);
    if want != len {
        let held = (len - 84) / 50;
        let place = if want > len {
            format!(
                "triangle {held} at byte {} is cut off (truncated, or a wrong count)",
                84 + 50 * held
            )
        } else {
            format!("{} bytes follow the last triangle", len - want)
        };
        return Err(format!(
            "binary STL: the count at byte 80 says {n} triangles ({want} bytes), the file has {len} bytes: {place}"
        ));
    }
    if n == 0 {
        return Err("binary STL: the count at byte 80 is 0 triangles".into());
    }
    let n = u64::from(n);
    let mut indices = Vec::new();
    reserve(&mut indices, n, "binary STL triangles")?;
    // a closed mesh has about n / 2 vertices
    let mut welder = Welder::with_capacity(n / 2 + 3)?;
    let block = block.clamp(1, n as usize);
    let mut current = Block::new(block)?;
    let mut next = Block::new(block)?;
    current.read(&mut file, 0, n)?;
    loop {
        let first = current.first;
        let end = first + current.corners.len() as u64 / 3;
        let weld = |welder: &mut Welder, indices: &mut Vec<[u32; 3]>, corners: &[Corner]| {
            welder
                .add(corners, indices)
                .map_err(|e| format!("binary STL: triangle {first}: {e}"))
        };
        if end == n {
            weld(&mut welder, &mut indices, &current.corners)?;
            break;
        }
        let (welded, read) = rayon::join(
            || weld(&mut welder, &mut indices, &current.corners),
            || next.read(&mut file, end, n),
        );
        welded?;
        read?;
        std::mem::swap(&mut current, &mut next);
    }
    Ok(finish(welder, indices, false))
}

/// A block of binary STL records read, and their corners (hashed for welding).
struct Block {
    bytes: Vec<u8>,
    corners: Vec<Corner>,
    /// The block's first triangle.
    first: u64,
}

impl Block {
    fn new(triangles: usize) -> Result<Self, String> {
        let mut block = Self {
            bytes: Vec::new(),
            corners: Vec::new(),
            first: 0,
        };
        reserve(&mut block.bytes, 50 * triangles as u64, "a read buffer")?;
        reserve(&mut block.corners, 3 * triangles as u64, "a read buffer")?;
        block.bytes.resize(50 * triangles, 0);
        Ok(block)
    }

    /// Reads the records from triangle `first` on (of `n`, the file's count) and decodes them,
    /// refusing corners that are not finite.
    fn read(&mut self, file: &mut std::fs::File, first: u64, n: u64) -> Result<(), String> {
        let count = (n - first).min(self.bytes.len() as u64 / 50) as usize;
        let bytes = &mut self.bytes[..50 * count];
        file.read_exact(bytes)
            .map_err(|e| format!("binary STL: triangle {first} at byte {}: {e}", 84 + 50 * first))?;
        self.first = first;
        self.corners.clear();
        let mut finite = true;
        for record in bytes.chunks_exact(50) {
            let xyz: &[u8; 36] = record[12..48].try_into().unwrap_or(&[0; 36]);
            for c in 0..3 {
                let p: [f32; 3] = std::array::from_fn(|k| {
                    let b = 12 * c + 4 * k;
                    f32::from_le_bytes([xyz[b], xyz[b + 1], xyz[b + 2], xyz[b + 3]])
                });
                let ok = |x: f32| x.to_bits() & 0x7f80_0000 != 0x7f80_0000;
                finite &= ok(p[0]) & ok(p[1]) & ok(p[2]);
                self.corners.push(Corner::new(p));
            }
        }
        if finite {
            return Ok(());
        }
        let j = self
            .corners
            .iter()
            .position(|c| !c.p.iter().all(|x| x.is_finite()))
            .unwrap_or(0);
        let t = first + j as u64 / 3;
        Err(format!(
            "binary STL: triangle {t} at byte {}: corner {} {:?} is not finite",
            84 + 50 * t,
            j % 3,
            self.corners[j].p
        ))
    }
}

/// The mesh of the welded corners.
pub(super) fn finish(welder: Welder, indices: Vec<[u32; 3]>, ascii: bool) -> Stl {
    let (corners, merged) = (welder.corners, welder.merged());
    Stl {
        data: MeshData {
            vertices: welder.vertices,
            indices,
            normals: None,
        },
        corners,
        merged,
        ascii,
    }
}
