//! Binary PLY payloads (`binary_little_endian`, `binary_big_endian`), decoded from one buffer.
//!
//! ply-rs-bw reads the header; this module reads the rest of the file into memory and walks the
//! elements in header order over byte slices. A record is its properties in header order with no
//! padding: a scalar takes its type's size (`char`/`uchar` 1, `short`/`ushort` 2,
//! `int`/`uint`/`float` 4, `double` 8 bytes); a list is its length (an integer of the count type)
//! followed by that many items. An element made only of scalars has a fixed record size and fixed
//! offsets; an element with a list is walked record by record.
//!
//! What is kept matches ply-rs-bw's path ([`super::read_ply_generic`]) exactly: `x, y, z` and
//! (when all three are present) `nx, ny, nz` of `vertex` as scalars of any type, converted to
//! `f32`; `vertex_indices` or `vertex_index` of `face` as a list of any integer type, fanned into
//! `(0, i, i + 1)`. Other properties and elements are skipped. Errors come in the same order:
//! the first element that cannot be read (naming it), a missing `vertex` or `face` element, the
//! first non-finite vertex, then the first bad face. Sizes are computed with checked arithmetic
//! and buffers are reserved fallibly, so a hostile header gives an error, never a panic or abort.

use super::{face_index_out_of_range, face_too_few_indices, vertex_not_finite, MeshData};
use ply_rs_bw::ply::{ElementDef, Encoding, Header, PropertyType, ScalarType};
use std::io::Read;

/// Reads the payload that follows `header` from `reader` (`size_hint`: an upper bound of its
/// length, used to reserve the buffer) and decodes it. The error is the message, without the path.
pub(super) fn read_payload(reader: &mut impl Read, size_hint: u64, header: &Header) -> Result<MeshData, String> {
    let mut bytes = Vec::new();
    let hint = usize::try_from(size_hint).unwrap_or(usize::MAX);
    bytes
        .try_reserve_exact(hint)
        .map_err(|_| format!("payload of {size_hint} bytes: too large to hold in memory"))?;
    reader.read_to_end(&mut bytes).map_err(|e| format!("payload: {e}"))?;
    decode(&bytes, header)
}

/// Decodes a binary payload held in memory (see the module documentation).
fn decode(bytes: &[u8], header: &Header) -> Result<MeshData, String> {
    match header.encoding {
        Encoding::BinaryLittleEndian => decode_in::<Little>(bytes, header),
        Encoding::BinaryBigEndian => decode_in::<Big>(bytes, header),
        Encoding::Ascii => Err("not a binary PLY payload".into()),
    }
}

/// The byte order of a binary payload.
trait Order {
    fn u16(b: [u8; 2]) -> u16;
    fn u32(b: [u8; 4]) -> u32;
    fn u64(b: [u8; 8]) -> u64;
}

struct Little;
struct Big;

impl Order for Little {
    fn u16(b: [u8; 2]) -> u16 {
        u16::from_le_bytes(b)
    }
    fn u32(b: [u8; 4]) -> u32 {
        u32::from_le_bytes(b)
    }
    fn u64(b: [u8; 8]) -> u64 {
        u64::from_le_bytes(b)
    }
}

impl Order for Big {
    fn u16(b: [u8; 2]) -> u16 {
        u16::from_be_bytes(b)
    }
    fn u32(b: [u8; 4]) -> u32 {
        u32::from_be_bytes(b)
    }
    fn u64(b: [u8; 8]) -> u64 {
        u64::from_be_bytes(b)
    }
}

/// The first `N` bytes of `b` (which holds at least `N`).
fn take<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut out = [0; N];
    out.copy_from_slice(&b[..N]);
    out
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn of(t: &ScalarType) -> Self {
        match t {
            ScalarType::Char => Ty::I8,
            ScalarType::UChar => Ty::U8,
            ScalarType::Short => Ty::I16,
            ScalarType::UShort => Ty::U16,
            ScalarType::Int => Ty::I32,
            ScalarType::UInt => Ty::U32,
            ScalarType::Float => Ty::F32,
            ScalarType::Double => Ty::F64,
        }
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }

    /// The value at the start of `b` as `f32` (`double` and 32-bit integers rounded).
    #[inline(always)]
    fn f32<O: Order>(self, b: &[u8]) -> f32 {
        match self {
            Ty::I8 => f32::from(b[0] as i8),
            Ty::U8 => f32::from(b[0]),
            Ty::I16 => f32::from(O::u16(take(b)) as i16),
            Ty::U16 => f32::from(O::u16(take(b))),
            Ty::I32 => O::u32(take(b)) as i32 as f32,
            Ty::U32 => O::u32(take(b)) as f32,
            Ty::F32 => f32::from_bits(O::u32(take(b))),
            Ty::F64 => f64::from_bits(O::u64(take(b))) as f32,
        }
    }

    /// The integer at the start of `b` (0 for the floating-point types, which are never read so).
    #[inline(always)]
    fn int<O: Order>(self, b: &[u8]) -> i64 {
        match self {
            Ty::I8 => i64::from(b[0] as i8),
            Ty::U8 => i64::from(b[0]),
            Ty::I16 => i64::from(O::u16(take(b)) as i16),
            Ty::U16 => i64::from(O::u16(take(b))),
            Ty::I32 => i64::from(O::u32(take(b)) as i32),
            Ty::U32 => i64::from(O::u32(take(b))),
            Ty::F32 | Ty::F64 => 0,
        }
    }
}

/// One property of a record.
#[derive(Clone, Copy, Debug)]
enum Field {
    Scalar(Ty),
    /// A list: its length's type (an integer type) and its items' type.
    List {
        count: Ty,
        item: Ty,
    },
}

/// Why an element could not be read.
#[derive(Clone, Copy, Debug)]
enum Cut {
    /// The payload ends inside record `record`.
    Truncated { record: usize },
    /// Record `record` has a list of negative length.
    NegativeLength { record: usize, length: i64 },
    /// A list's length has a floating-point type.
    FloatLength(Ty),
    /// More records than memory can hold.
    TooMany,
}

impl Cut {
    fn message(&self, name: &str, count: usize) -> String {
        let detail = match self {
            Cut::Truncated { record } => format!("unexpected end of file (truncated?) in record {record}"),
            Cut::NegativeLength { record, length } => format!("record {record}: list length {length} is negative"),
            Cut::FloatLength(t) => format!("list length type {t:?} is not an integer type"),
            Cut::TooMany => "too many records to hold in memory".into(),
        };
        format!("element `{name}` ({count} expected): {detail}")
    }
}

/// The records of one element: its fields in header order, with fixed offsets and size when it
/// has no list.
struct Layout {
    fields: Vec<Field>,
    /// Each field's offset in a record, when the size is fixed.
    offsets: Vec<usize>,
    /// The record size, when fixed.
    size: Option<usize>,
    /// The smallest possible record size (empty lists).
    min_size: usize,
}

impl Layout {
    fn new(element: &ElementDef) -> Result<Self, Cut> {
        let fields: Vec<Field> = element
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) => Field::Scalar(Ty::of(t)),
                PropertyType::List(count, item) => Field::List {
                    count: Ty::of(count),
                    item: Ty::of(item),
                },
            })
            .collect();
        let mut offsets = Vec::with_capacity(fields.len());
        let mut min_size = 0;
        let mut fixed = true;
        for field in &fields {
            offsets.push(min_size);
            min_size += match *field {
                Field::Scalar(t) => t.size(),
                Field::List { count, .. } => {
                    fixed = false;
                    // ply-rs-bw rejects such a list when it reads the first record
                    if !count.is_integer() && element.count > 0 {
                        return Err(Cut::FloatLength(count));
                    }
                    count.size()
                }
            };
        }
        Ok(Self {
            fields,
            offsets,
            size: fixed.then_some(min_size),
            min_size,
        })
    }

    /// Walks the record that starts at `bytes[0]`: writes each field's offset into `at` and
    /// returns the record's size. `record` is the record's number, for errors.
    #[inline(always)]
    fn walk<O: Order>(&self, bytes: &[u8], record: usize, at: &mut [usize]) -> Result<usize, Cut> {
        let truncated = Cut::Truncated { record };
        let mut pos = 0usize;
        for (field, at) in self.fields.iter().zip(at) {
            *at = pos;
            let len = match *field {
                Field::Scalar(t) => t.size(),
                Field::List { count, item } => {
                    let head = bytes.get(pos..pos + count.size()).ok_or(truncated)?;
                    let length = count.int::<O>(head);
                    let n = usize::try_from(length).map_err(|_| Cut::NegativeLength { record, length })?;
                    n.checked_mul(item.size())
                        .and_then(|b| b.checked_add(count.size()))
                        .ok_or(truncated)?
                }
            };
            pos = pos.checked_add(len).ok_or(truncated)?;
            if pos > bytes.len() {
                return Err(truncated);
            }
        }
        Ok(pos)
    }

    /// The bytes of `count` fixed-size records at the start of `bytes`.
    fn fixed_block<'a>(&self, bytes: &'a [u8], size: usize, count: usize) -> Result<&'a [u8], Cut> {
        match count.checked_mul(size) {
            Some(total) if total <= bytes.len() => Ok(&bytes[..total]),
            _ => Err(Cut::Truncated {
                record: bytes.len() / size.max(1),
            }),
        }
    }

    /// A capacity for `count` records in `bytes`: at most as many as could fit.
    fn capacity(&self, bytes: &[u8], count: usize) -> usize {
        count.min(bytes.len() / self.min_size.max(1))
    }

    /// The number of bytes taken by `count` records at the start of `bytes`.
    fn skip<O: Order>(&self, bytes: &[u8], count: usize) -> Result<usize, Cut> {
        if let Some(size) = self.size {
            return Ok(self.fixed_block(bytes, size, count)?.len());
        }
        let mut at = vec![0; self.fields.len()];
        let mut pos = 0;
        for record in 0..count {
            pos += self.walk::<O>(&bytes[pos..], record, &mut at)?;
        }
        Ok(pos)
    }
}

/// The `vertex` element, read.
struct Vertices {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    /// The first vertex whose position is not finite, and that position.
    first_bad: Option<(usize, [f32; 3])>,
}

/// Reads `count` vertices from the start of `bytes`; returns them and the bytes taken.
fn read_vertices<O: Order>(bytes: &[u8], element: &ElementDef, layout: &Layout) -> Result<(Vertices, usize), Cut> {
    let count = element.count;
    // a scalar field by name: its index and type (ply-rs-bw's path ignores lists so named)
    let field = |name: &str| match element.properties.get_index_of(name).map(|k| (k, layout.fields[k])) {
        Some((k, Field::Scalar(t))) => Some((k, t)),
        _ => None,
    };
    let position = [field("x"), field("y"), field("z")];
    let normal = match (field("nx"), field("ny"), field("nz")) {
        (Some(x), Some(y), Some(z)) => Some([x, y, z]),
        _ => None,
    };
    let read = |record: &[u8], at: &[usize]| {
        let get = |(k, t): (usize, Ty)| t.f32::<O>(&record[at[k]..]);
        let coordinate = |f: Option<(usize, Ty)>| f.map_or(f32::NAN, get);
        let p = [
            coordinate(position[0]),
            coordinate(position[1]),
            coordinate(position[2]),
        ];
        let n = normal.map(|[x, y, z]| [get(x), get(y), get(z)]);
        (p, n)
    };
    let capacity = layout.capacity(bytes, count);
    let mut out = Vertices {
        positions: Vec::new(),
        // as ply-rs-bw's path: normals when every vertex has them (so also for no vertices)
        normals: (normal.is_some() || count == 0).then(Vec::new),
        first_bad: None,
    };
    out.positions.try_reserve_exact(capacity).map_err(|_| Cut::TooMany)?;
    if let Some(normals) = &mut out.normals {
        normals.try_reserve_exact(capacity).map_err(|_| Cut::TooMany)?;
    }
    let mut keep = |i: usize, (p, n): ([f32; 3], Option<[f32; 3]>)| {
        if !p.iter().all(|x| x.is_finite()) {
            out.first_bad = Some((i, p));
            return false;
        }
        out.positions.push(p);
        if let (Some(normals), Some(n)) = (&mut out.normals, n) {
            normals.push(n);
        }
        true
    };
    let used = match layout.size {
        Some(0) => {
            // no properties: positions missing; the first vertex (if any) is the error
            if count > 0 {
                keep(0, read(&[], &[]));
            }
            0
        }
        Some(size) => {
            let block = layout.fixed_block(bytes, size, count)?;
            for (i, record) in block.chunks_exact(size).enumerate() {
                if !keep(i, read(record, &layout.offsets)) {
                    break;
                }
            }
            block.len()
        }
        None => {
            let mut at = vec![0; layout.fields.len()];
            let mut pos = 0;
            let mut good = true;
            for i in 0..count {
                let len = layout.walk::<O>(&bytes[pos..], i, &mut at)?;
                if good {
                    good = keep(i, read(&bytes[pos..pos + len], &at));
                }
                pos += len;
            }
            pos
        }
    };
    Ok((out, used))
}

/// The first bad face: too few indices, or an index out of range.
enum BadFace {
    TooFew { face: usize, n: usize },
    OutOfRange { face: usize, index: i64 },
}

/// The `face` element, read.
struct Faces {
    triangles: Vec<[u32; 3]>,
    first_bad: Option<BadFace>,
}

/// Reads `count` faces from the start of `bytes` (indices checked against `nv` vertices); returns
/// them and the bytes taken.
fn read_faces<O: Order>(bytes: &[u8], element: &ElementDef, layout: &Layout, nv: usize) -> Result<(Faces, usize), Cut> {
    let count = element.count;
    // ply-rs-bw's path keeps the last integer list of either name
    let list = element
        .properties
        .values()
        .zip(&layout.fields)
        .enumerate()
        .filter(|(_, (p, field))| {
            (p.name == "vertex_indices" || p.name == "vertex_index")
                && matches!(field, Field::List { item, .. } if item.is_integer())
        })
        .map(|(k, (_, field))| (k, *field))
        .next_back();
    let mut out = Faces {
        triangles: Vec::new(),
        first_bad: None,
    };
    let Some((k, Field::List { count: count_ty, item })) = list else {
        if count > 0 {
            out.first_bad = Some(BadFace::TooFew { face: 0, n: 0 });
        }
        return Ok((out, layout.skip::<O>(bytes, count)?));
    };
    out.triangles
        .try_reserve(layout.capacity(bytes, count))
        .map_err(|_| Cut::TooMany)?;
    let (head, size) = (count_ty.size(), item.size());
    let mut at = vec![0; layout.fields.len()];
    let mut indices: Vec<i64> = Vec::with_capacity(16);
    let mut pos = 0;
    for face in 0..count {
        let record = &bytes[pos..];
        let len = layout.walk::<O>(record, face, &mut at)?;
        pos += len;
        if out.first_bad.is_some() {
            continue;
        }
        // the walk checked the length and that the items lie inside the record
        let start = at[k];
        let n = count_ty.int::<O>(&record[start..]) as usize;
        let items = &record[start + head..start + head + n * size];
        if n == 3 {
            // the common case, without the scratch list
            let (a, b, c) = (
                item.int::<O>(items),
                item.int::<O>(&items[size..]),
                item.int::<O>(&items[2 * size..]),
            );
            match [a, b, c].into_iter().find(|&i| i < 0 || i as usize >= nv) {
                Some(index) => out.first_bad = Some(BadFace::OutOfRange { face, index }),
                None => out.triangles.push([a as u32, b as u32, c as u32]),
            }
            continue;
        }
        indices.clear();
        indices.extend(items.chunks_exact(size).map(|b| item.int::<O>(b)));
        if n < 3 {
            out.first_bad = Some(BadFace::TooFew { face, n });
            continue;
        }
        if let Some(&index) = indices.iter().find(|&&i| i < 0 || i as usize >= nv) {
            out.first_bad = Some(BadFace::OutOfRange { face, index });
            continue;
        }
        let first = indices[0] as u32;
        for pair in indices[1..].windows(2) {
            out.triangles.push([first, pair[0] as u32, pair[1] as u32]);
        }
    }
    Ok((out, pos))
}

/// Reads the element `name` from the start of `bytes` into `vertices` or `faces` (or skips it);
/// returns the bytes taken.
fn read_element<O: Order>(
    bytes: &[u8],
    name: &str,
    element: &ElementDef,
    nv: usize,
    vertices: &mut Option<Vertices>,
    faces: &mut Option<Faces>,
) -> Result<usize, Cut> {
    let layout = Layout::new(element)?;
    Ok(match name {
        "vertex" => {
            let (v, used) = read_vertices::<O>(bytes, element, &layout)?;
            *vertices = Some(v);
            used
        }
        "face" => {
            let (f, used) = read_faces::<O>(bytes, element, &layout, nv)?;
            *faces = Some(f);
            used
        }
        _ => layout.skip::<O>(bytes, element.count)?,
    })
}

fn decode_in<O: Order>(bytes: &[u8], header: &Header) -> Result<MeshData, String> {
    let nv = header.elements.get("vertex").map_or(0, |e| e.count);
    let (mut vertices, mut faces) = (None, None);
    let mut pos = 0;
    for (name, element) in &header.elements {
        pos += read_element::<O>(&bytes[pos..], name, element, nv, &mut vertices, &mut faces)
            .map_err(|cut| cut.message(name, element.count))?;
    }
    let vertices = vertices.ok_or("no `vertex` element")?;
    let faces = faces.ok_or("no `face` element")?;
    if let Some((i, p)) = vertices.first_bad {
        return Err(vertex_not_finite(i, p));
    }
    match faces.first_bad {
        Some(BadFace::TooFew { face, n }) => Err(face_too_few_indices(face, n)),
        Some(BadFace::OutOfRange { face, index }) => Err(face_index_out_of_range(face, index, nv)),
        None => Ok(MeshData {
            vertices: vertices.positions,
            indices: faces.triangles,
            normals: vertices.normals,
        }),
    }
}
