//! The text and binary readers against the reference readers: the same results and messages for
//! random files, sound and damaged, read in blocks and pieces of many sizes.

use super::super::off::read_off_cut;
use super::super::stl_ascii::read_ascii_cut;
use super::super::text::{Cuts, CUTS};
use super::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::fmt::Write as _;

/// A coordinate written in one of the ways files write them.
fn number(rng: &mut StdRng, x: f32) -> String {
    match rng.random_range(0..8) {
        0 => format!("{x:e}"),
        1 => format!("{x:.9}"),
        2 => format!("{x:+}"),
        3 => format!("{x:E}"),
        4 => format!("{}", f64::from(x)),
        _ => format!("{x}"),
    }
}

fn coordinate_value(rng: &mut StdRng) -> f32 {
    match rng.random_range(0..10) {
        0 => 0.0,
        1 => -0.0,
        2 => rng.random_range(-3..4) as f32,
        3 => f32::from_bits(rng.random::<u32>() & 0x3fff_ffff),
        _ => rng.random_range(-2.0..2.0),
    }
}

/// A small mesh with shared vertices (and a degenerate triangle at times).
fn mesh(rng: &mut StdRng) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let nv = rng.random_range(3..40);
    let vertices: Vec<[f32; 3]> = (0..nv)
        .map(|_| std::array::from_fn(|_| coordinate_value(rng)))
        .collect();
    let nt = rng.random_range(1..60);
    let indices = (0..nt)
        .map(|_| std::array::from_fn(|_| rng.random_range(0..nv as u32)))
        .collect();
    (vertices, indices)
}

fn newline(rng: &mut StdRng, crlf: bool) -> &'static str {
    match (crlf, rng.random_range(0..40)) {
        (_, 0) => "\n\n",
        (_, 1) => "  \n",
        (true, _) => "\r\n",
        (false, _) => "\n",
    }
}

fn ascii_stl(rng: &mut StdRng) -> Vec<u8> {
    let (v, t) = mesh(rng);
    let crlf = rng.random_bool(0.2);
    let upper = rng.random_bool(0.1);
    let word = |w: &str| if upper { w.to_uppercase() } else { w.to_string() };
    let indent = ["", "  ", "\t", " \t "][rng.random_range(0..4)];
    let mut s = String::new();
    let solids = rng.random_range(1..3);
    let per = t.len().div_ceil(solids);
    for chunk in t.chunks(per) {
        let _ = write!(s, "{} name{}", word("solid"), newline(rng, crlf));
        for tri in chunk {
            let normal = if rng.random_bool(0.1) {
                "  0 0 1 extra"
            } else {
                " 0 0 0"
            };
            let _ = write!(s, "{indent}{} normal{normal}{}", word("facet"), newline(rng, crlf));
            let _ = write!(
                s,
                "{indent}{indent}{} {}{}",
                word("outer"),
                word("loop"),
                newline(rng, crlf)
            );
            for &i in tri {
                let p = v[i as usize];
                let sep = if rng.random_bool(0.05) { "\t " } else { " " };
                let tail = if rng.random_bool(0.03) { " 9" } else { "" };
                let _ = write!(
                    s,
                    "{indent}{indent}{indent}{}{sep}{}{sep}{}{sep}{}{tail}{}",
                    word("vertex"),
                    number(rng, p[0]),
                    number(rng, p[1]),
                    number(rng, p[2]),
                    newline(rng, crlf)
                );
            }
            let _ = write!(s, "{indent}{indent}{}{}", word("endloop"), newline(rng, crlf));
            let _ = write!(s, "{indent}{}{}", word("endfacet"), newline(rng, crlf));
        }
        let _ = write!(s, "{} name{}", word("endsolid"), newline(rng, crlf));
    }
    if rng.random_bool(0.2) {
        s.pop();
    }
    s.into_bytes()
}

fn off(rng: &mut StdRng) -> Vec<u8> {
    let (v, t) = mesh(rng);
    let crlf = rng.random_bool(0.2);
    let mut s = String::new();
    if rng.random_bool(0.2) {
        let _ = write!(s, "# a comment{}", newline(rng, crlf));
    }
    let keyword = ["OFF", "COFF", "NOFF", "STOFF"][rng.random_range(0..4)];
    if rng.random_bool(0.3) {
        let _ = write!(s, "{keyword} {} {} 0{}", v.len(), t.len(), newline(rng, crlf));
    } else {
        let _ = write!(
            s,
            "{keyword}{}{} {} 0{}",
            newline(rng, crlf),
            v.len(),
            t.len(),
            newline(rng, crlf)
        );
    }
    for p in &v {
        if rng.random_bool(0.05) {
            let _ = write!(s, "# between{}", newline(rng, crlf));
        }
        let extra = [" ", " 0.5 0.5 0.5", " # note", "\t", "#x"][rng.random_range(0..5)];
        let _ = write!(
            s,
            "{} {} {}{extra}{}",
            number(rng, p[0]),
            number(rng, p[1]),
            number(rng, p[2]),
            newline(rng, crlf)
        );
    }
    for tri in &t {
        if rng.random_bool(0.1) {
            let d = rng.random_range(0..v.len());
            let _ = write!(s, "4 {} {} {} {d}{}", tri[0], tri[1], tri[2], newline(rng, crlf));
        } else {
            let extra = ["", " 255 0 0", " # c", "  "][rng.random_range(0..4)];
            let _ = write!(s, "3 {} {} {}{extra}{}", tri[0], tri[1], tri[2], newline(rng, crlf));
        }
    }
    if rng.random_bool(0.3) {
        s.push_str("trailing words\n");
    }
    let mut b = s.into_bytes();
    if rng.random_bool(0.1) {
        b.extend_from_slice(b"\xff\xfe after the last face\n");
    }
    b
}

/// `bytes` with a mistake made at a random line, or cut short.
fn damage(rng: &mut StdRng, bytes: &[u8]) -> Vec<u8> {
    let starts: Vec<usize> = std::iter::once(0)
        .chain(
            bytes
                .iter()
                .enumerate()
                .filter(|(_, &c)| c == b'\n')
                .map(|(i, _)| i + 1),
        )
        .filter(|&i| i < bytes.len())
        .collect();
    let at = starts[rng.random_range(0..starts.len())];
    let end = bytes[at..]
        .iter()
        .position(|&c| c == b'\n')
        .map_or(bytes.len(), |i| at + i + 1);
    let insert = |text: &[u8]| [&bytes[..at], text, &bytes[at..]].concat();
    let replace = |text: &[u8]| [&bytes[..at], text, &bytes[end..]].concat();
    match rng.random_range(0..12) {
        0 => bytes[..rng.random_range(0..bytes.len())].to_vec(),
        1 => replace(b""),
        2 => insert(&bytes[at..end]),
        3 => replace(b"hello world\n"),
        4 => insert(b"\xc3\x28 bad\n"),
        5 => replace(b"  vertex 1 nan 2\n"),
        6 => replace(b"vertex 1 2 abc\n"),
        7 => replace(b"1 2 3 1e39\n"),
        8 => replace(b"3 0 1 99999\n"),
        9 => replace(b"2 0 1\n"),
        10 => replace(b"3 0 -1 2\n"),
        _ => replace(b"endloop\n"),
    }
}

fn cuts(rng: &mut StdRng) -> [Cuts; 3] {
    let small = Cuts {
        block: rng.random_range(8..300),
        piece: rng.random_range(1..100),
    };
    [
        CUTS,
        small,
        Cuts {
            block: 1 << 20,
            piece: 64,
        },
    ]
}

fn same_stl(expected: &Result<Stl, String>, got: &Result<super::super::stl::Stl, String>, case: &str) {
    match (expected, got) {
        (Ok(e), Ok(g)) => {
            let bits = |v: &[[f32; 3]]| v.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&e.data.vertices), bits(&g.data.vertices), "{case}");
            assert_eq!(e.data.indices, g.data.indices, "{case}");
            assert_eq!((e.corners, e.merged, e.ascii), (g.corners, g.merged, g.ascii), "{case}");
        }
        (Err(e), Err(g)) => assert_eq!(e, g, "{case}"),
        (e, g) => panic!("{case}: {:?} against {:?}", e.as_ref().err(), g.as_ref().err()),
    }
}

fn same_off(expected: &Result<MeshData, String>, got: &Result<MeshData, String>, case: &str) {
    match (expected, got) {
        (Ok(e), Ok(g)) => {
            let bits = |v: &[[f32; 3]]| v.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&e.vertices), bits(&g.vertices), "{case}");
            assert_eq!(e.indices, g.indices, "{case}");
        }
        (Err(e), Err(g)) => assert_eq!(e, g, "{case}"),
        (e, g) => panic!("{case}: {:?} against {:?}", e.as_ref().err(), g.as_ref().err()),
    }
}

#[test]
fn ascii_stl_in_blocks_and_pieces_reads_as_line_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.stl");
    let mut rng = StdRng::seed_from_u64(45);
    let (mut fine, mut refused) = (0, 0);
    for case in 0..600 {
        let mut bytes = ascii_stl(&mut rng);
        if case % 2 == 1 {
            bytes = damage(&mut rng, &bytes);
        }
        std::fs::write(&path, &bytes).unwrap();
        let expected = read_ascii(&path);
        if expected.is_ok() {
            fine += 1
        } else {
            refused += 1
        }
        for c in cuts(&mut rng) {
            same_stl(&expected, &read_ascii_cut(&path, c), &format!("case {case}, {c:?}"));
        }
    }
    assert!(fine > 250 && refused > 150, "{fine} read, {refused} refused");
}

#[test]
fn off_in_blocks_and_pieces_reads_as_line_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.off");
    let mut rng = StdRng::seed_from_u64(46);
    let (mut fine, mut refused) = (0, 0);
    for case in 0..600 {
        let mut bytes = off(&mut rng);
        if case % 2 == 1 {
            bytes = damage(&mut rng, &bytes);
        }
        std::fs::write(&path, &bytes).unwrap();
        let expected = read_off(&path);
        if expected.is_ok() {
            fine += 1
        } else {
            refused += 1
        }
        for c in cuts(&mut rng) {
            same_off(&expected, &read_off_cut(&path, c), &format!("case {case}, {c:?}"));
        }
    }
    assert!(fine > 250 && refused > 150, "{fine} read, {refused} refused");
}

#[test]
fn binary_stl_in_blocks_reads_as_record_by_record() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.stl");
    let mut rng = StdRng::seed_from_u64(47);
    for case in 0..400 {
        let (v, t) = mesh(&mut rng);
        let mut bytes = vec![b' '; 80];
        bytes.extend((t.len() as u32).to_le_bytes());
        for tri in &t {
            bytes.extend([0u8; 12]);
            for &i in tri {
                bytes.extend(v[i as usize].iter().flat_map(|x| x.to_le_bytes()));
            }
            bytes.extend([0u8; 2]);
        }
        if case % 3 == 1 {
            let at = 84 + 50 * rng.random_range(0..t.len()) + 12 + 4 * rng.random_range(0..9);
            let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][rng.random_range(0..3)];
            bytes[at..at + 4].copy_from_slice(&bad.to_le_bytes());
        }
        std::fs::write(&path, &bytes).unwrap();
        let len = bytes.len() as u64;
        let expected = read_binary(&path, len);
        for block in [1, 2, 3, 7, 1 << 14] {
            let got = super::super::stl::read_binary_blocks(&path, len, block);
            same_stl(&expected, &got, &format!("case {case}, blocks of {block}"));
        }
    }
}

#[test]
fn a_large_grid_reads_alike_in_every_cut() {
    let n = 120usize;
    let v: Vec<[f32; 3]> = (0..n * n)
        .map(|k| {
            [
                (k % n) as f32 / 7.0,
                (k / n) as f32 / 3.0,
                ((k * 7919) % 13) as f32 - 6.0,
            ]
        })
        .collect();
    let mut t = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let k = (y * n + x) as u32;
            t.push([k, k + 1, k + n as u32]);
            t.push([k + 1, k + n as u32 + 1, k + n as u32]);
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grid.stl");
    let mut bytes = vec![b' '; 80];
    bytes.extend((t.len() as u32).to_le_bytes());
    let mut text = String::from("solid grid\n");
    for tri in &t {
        bytes.extend([0u8; 12]);
        text.push_str("facet normal 0 0 1\nouter loop\n");
        for &i in tri {
            let p = v[i as usize];
            bytes.extend(p.iter().flat_map(|x| x.to_le_bytes()));
            let _ = writeln!(text, "vertex {} {} {}", p[0], p[1], p[2]);
        }
        text.push_str("endloop\nendfacet\n");
        bytes.extend([0u8; 2]);
    }
    text.push_str("endsolid grid\n");
    std::fs::write(&path, &bytes).unwrap();
    let expected = read_binary(&path, bytes.len() as u64);
    for block in [1000, 4097, 1 << 14] {
        let got = super::super::stl::read_binary_blocks(&path, bytes.len() as u64, block);
        same_stl(&expected, &got, &format!("binary, blocks of {block}"));
    }
    assert_eq!(expected.unwrap().data.vertices.len(), n * n);
    std::fs::write(&path, &text).unwrap();
    let expected = read_ascii(&path);
    for c in [
        CUTS,
        Cuts {
            block: 70_000,
            piece: 9_000,
        },
        Cuts {
            block: 1 << 20,
            piece: 100_000,
        },
    ] {
        same_stl(&expected, &read_ascii_cut(&path, c), &format!("ASCII, {c:?}"));
    }
    let mut off = format!("OFF\n{} {} 0\n", v.len(), t.len());
    for p in &v {
        let _ = writeln!(off, "{} {} {}", p[0], p[1], p[2]);
    }
    for tri in &t {
        let _ = writeln!(off, "3 {} {} {}", tri[0], tri[1], tri[2]);
    }
    let path = dir.path().join("grid.off");
    std::fs::write(&path, &off).unwrap();
    let expected = read_off(&path);
    for c in [
        CUTS,
        Cuts {
            block: 70_000,
            piece: 9_000,
        },
        Cuts {
            block: 1 << 20,
            piece: 100_000,
        },
    ] {
        same_off(&expected, &read_off_cut(&path, c), &format!("OFF, {c:?}"));
    }
}

#[test]
fn long_lines_are_refused_alike_at_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.stl");
    let body = "facet normal 0 0 0\nouter loop\nvertex 1 2 3\nvertex 4 5 6\nvertex 7 8 9\nendloop\nendfacet\n";
    for pad in [MAX_LINE_BYTES - 12, MAX_LINE_BYTES - 11, MAX_LINE_BYTES + 5] {
        // a vertex line padded with spaces to about the limit, in the middle of the file
        let long = format!("vertex 1 2 3{}\n", " ".repeat(pad - 12));
        let text = format!(
            "solid x\n{body}{}{body}endsolid x\n",
            body.replacen("vertex 1 2 3\n", &long, 1)
        );
        std::fs::write(&path, &text).unwrap();
        let expected = read_ascii(&path);
        for c in [CUTS, Cuts { block: 100, piece: 30 }] {
            same_stl(&expected, &read_ascii_cut(&path, c), &format!("pad {pad}, {c:?}"));
        }
    }
    let path = dir.path().join("t.off");
    for pad in [MAX_LINE_BYTES - 6, MAX_LINE_BYTES - 5, MAX_LINE_BYTES + 5] {
        let long = format!("0 0 1{}\n", " ".repeat(pad - 5));
        let text = format!("OFF\n3 1 0\n0 0 0\n1 0 0\n{long}3 0 1 2\n");
        std::fs::write(&path, &text).unwrap();
        let expected = read_off(&path);
        for c in [CUTS, Cuts { block: 100, piece: 30 }] {
            same_off(&expected, &read_off_cut(&path, c), &format!("pad {pad}, {c:?}"));
        }
    }
}
