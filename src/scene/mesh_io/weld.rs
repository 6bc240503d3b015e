//! Exact vertex welding of triangle corners (STL): positions whose coordinates compare equal
//! become one vertex.

use super::shared::reserve;
use zeroset_primitives::bvh::prefetch;

/// A corner to weld: its position and the hash of its key (computed where the corner is read,
/// so off the welding thread).
#[derive(Clone, Copy, Debug)]
pub(super) struct Corner {
    pub p: [f32; 3],
    h: u32,
}

impl Corner {
    #[inline(always)]
    pub fn new(p: [f32; 3]) -> Self {
        Self { p, h: hash(p) }
    }
}

/// Exact vertex welding: positions whose coordinates compare equal become one vertex.
///
/// Equality is `f32` equality of each coordinate: bit-equal positions, and also `-0.0` against
/// `0.0` (the same point; keeping them apart would open a crack along every edge through it).
/// The welded vertex keeps the first occurrence's bits, and the vertices are numbered in order of
/// first occurrence. Positions must be finite (the readers refuse NaN before welding).
///
/// An open-addressing table of vertex indices (linear probing, grown at half full), behind a
/// small cache of the vertices last looked up (neighbouring triangles share corners: in a mesh
/// written in order, most lookups end there). Table lookups miss the caches on a large mesh, so
/// they are overlapped: the table slot of the corner [`FAR`] corners ahead is prefetched where
/// that corner is not among the recent ones.
pub(super) struct Welder {
    /// The welded vertices, in order of first occurrence.
    pub vertices: Vec<[f32; 3]>,
    slots: Vec<u32>,
    mask: usize,
    /// Corners seen.
    pub corners: u64,
    /// The corners of a triangle begun in an earlier [`Welder::add`] (`open` of them).
    triangle: [u32; 3],
    open: usize,
    /// The vertices last looked up, by hash: key and index (`EMPTY` for none), checked before
    /// the table.
    recent: Vec<[u32; 4]>,
}

const EMPTY: u32 = u32::MAX;

/// How many corners ahead a table slot is prefetched.
const FAR: usize = 64;
/// Entries of the cache of recent vertices (16 KiB).
const RECENT: usize = 1 << 10;

/// The entry of hash `h` in the cache of recent vertices.
#[inline(always)]
fn recent_slot(h: u32) -> usize {
    (h >> 20) as usize & (RECENT - 1)
}

/// The key of a position: its bits with `-0.0` made `+0.0`.
#[inline(always)]
fn key(p: [f32; 3]) -> [u32; 3] {
    p.map(|x| (x + 0.0).to_bits())
}

#[inline(always)]
fn hash(p: [f32; 3]) -> u32 {
    let k = key(p);
    let a = u64::from(k[0]) | (u64::from(k[1]) << 32);
    let h = (a ^ (a >> 29)).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ u64::from(k[2]);
    let h = h.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    (h ^ (h >> 32)) as u32
}

fn empty_slots(size: usize) -> Result<Vec<u32>, String> {
    let mut slots = Vec::new();
    reserve(&mut slots, size as u64, "vertex table")?;
    slots.resize(size, EMPTY);
    Ok(slots)
}

impl Welder {
    /// A welder expecting about `vertices` distinct positions (the table grows past that).
    pub fn with_capacity(vertices: u64) -> Result<Self, String> {
        let want = vertices.clamp(16, 1 << 28).next_power_of_two() * 2;
        let mut out = Vec::new();
        reserve(&mut out, vertices.min(1 << 28), "vertices")?;
        Ok(Self {
            vertices: out,
            slots: empty_slots(want as usize)?,
            mask: want as usize - 1,
            corners: 0,
            triangle: [0; 3],
            open: 0,
            recent: vec![[0, 0, 0, EMPTY]; RECENT],
        })
    }

    /// Welds the next `corners` of the triangles, appending each triangle completed to `out`
    /// (a triangle may span calls). Errors past 2³² − 2 vertices or when memory runs out.
    pub fn add(&mut self, corners: &[Corner], out: &mut Vec<[u32; 3]>) -> Result<(), String> {
        let triangles = (self.open + corners.len()) / 3;
        if out.capacity() - out.len() < triangles {
            reserve(out, triangles.max(out.len()) as u64, "triangles")?;
        }
        for (j, c) in corners.iter().enumerate() {
            // prefetch where the cache of recent vertices misses now
            if let Some(ahead) = corners.get(j + FAR) {
                if !self.is_recent(ahead.p, ahead.h) {
                    prefetch(self.slots.as_ptr().wrapping_add(ahead.h as usize & self.mask));
                }
            }
            self.triangle[self.open] = self.index(c.p, c.h)?;
            self.open += 1;
            if self.open == 3 {
                out.push(self.triangle);
                self.open = 0;
            }
        }
        Ok(())
    }

    /// Whether `p` (of hash `h`) is in the cache of recent vertices.
    #[inline(always)]
    fn is_recent(&self, p: [f32; 3], h: u32) -> bool {
        let r = self.recent[recent_slot(h)];
        r[3] != EMPTY && [r[0], r[1], r[2]] == key(p)
    }

    /// The index of `p` (of hash `h`), added if new.
    #[inline(always)]
    fn index(&mut self, p: [f32; 3], h: u32) -> Result<u32, String> {
        self.corners += 1;
        let k = key(p);
        let r = recent_slot(h);
        let e = self.recent[r];
        if e[3] != EMPTY && [e[0], e[1], e[2]] == k {
            return Ok(e[3]);
        }
        let mut i = h as usize & self.mask;
        loop {
            let s = self.slots[i];
            if s == EMPTY {
                break;
            }
            if key(self.vertices[s as usize]) == k {
                self.recent[r] = [k[0], k[1], k[2], s];
                return Ok(s);
            }
            i = (i + 1) & self.mask;
        }
        let n = self.vertices.len();
        if n >= EMPTY as usize - 1 {
            return Err("more than 2³² − 2 distinct vertices".into());
        }
        if n == self.vertices.capacity() {
            reserve(&mut self.vertices, n.max(16) as u64, "vertices")?;
        }
        self.vertices.push(p);
        self.slots[i] = n as u32;
        self.recent[r] = [k[0], k[1], k[2], n as u32];
        if 2 * (n + 1) > self.slots.len() {
            self.grow()?;
        }
        Ok(n as u32)
    }

    #[cold]
    fn grow(&mut self) -> Result<(), String> {
        let size = self.slots.len() * 2;
        let mut slots = empty_slots(size)?;
        let mask = size - 1;
        for (n, &v) in self.vertices.iter().enumerate() {
            let mut i = hash(v) as usize & mask;
            while slots[i] != EMPTY {
                i = (i + 1) & mask;
            }
            slots[i] = n as u32;
        }
        self.slots = slots;
        self.mask = mask;
        Ok(())
    }

    /// Corners merged into an earlier vertex (corners − distinct vertices).
    pub fn merged(&self) -> u64 {
        self.corners - self.vertices.len() as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welding_numbers_first_occurrences_and_merges_zeros() {
        let mut w = Welder::with_capacity(1).unwrap();
        let mut out = Vec::new();
        let a = [1.0, 2.0, 3.0];
        let z = [0.0, -0.0, 0.0];
        let mz = [-0.0, 0.0, -0.0];
        let corners = |ps: &[[f32; 3]]| ps.iter().map(|&p| Corner::new(p)).collect::<Vec<_>>();
        w.add(&corners(&[a, z, a, mz]), &mut out).unwrap();
        assert_eq!(out, vec![[0, 1, 0]]);
        w.add(&corners(&[[4.0; 3], a]), &mut out).unwrap();
        assert_eq!(out, vec![[0, 1, 0], [1, 2, 0]]);
        assert_eq!(w.vertices[1].map(f32::to_bits), z.map(f32::to_bits));
        assert_eq!((w.corners, w.merged()), (6, 3));
        // growing keeps every vertex findable
        let many: Vec<[f32; 3]> = (0..3000).map(|i| [i as f32, (i % 7) as f32, 0.5]).collect();
        let mut again = Vec::new();
        w.add(&corners(&many), &mut again).unwrap();
        w.add(&corners(&many), &mut again).unwrap();
        assert_eq!(again[..1000], again[1000..]);
        assert_eq!(w.vertices.len(), 3 + 3000);
    }
}
