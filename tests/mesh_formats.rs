//! STL (binary and ASCII), OFF and glTF / GLB beside OBJ and PLY: the same triangles and the
//! same hits as the PLY they are written from, exact welding of STL corners (a closed STL is
//! watertight), glTF node transforms and primitive modes, and malformed files refused with
//! their place named, also under a 2 GB address-space limit.

mod support;
#[path = "support/mesh_writers.rs"]
mod writers;

use glam::DVec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};
use zeroset::scene::mesh_io::{load_mesh, read_mesh, read_mesh_report, MeshData};
use zeroset::scene::registry::BuildContext;
use zeroset::scene::Scene;
use zeroset_primitives::{Intersect, Interval, Mesh, Ray, Triangle};

fn icosphere() -> MeshData {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/icosphere2.ply");
    read_mesh(&path).unwrap()
}

fn corners(d: &MeshData, t: usize) -> [[f32; 3]; 3] {
    d.indices[t].map(|i| d.vertices[i as usize])
}

fn bits(c: [[f32; 3]; 3]) -> [[u32; 3]; 3] {
    c.map(|p| p.map(f32::to_bits))
}

/// The five files of `d` in `dir`: binary STL (twice: a plain header and one starting with
/// `solid`), ASCII STL, OFF, GLB, glTF with an external buffer (`my data.bin`).
fn write_all(dir: &Path, d: &MeshData) -> Vec<PathBuf> {
    let (v, i) = (&d.vertices, &d.indices);
    let files = [
        ("binary.stl", writers::binary_stl(v, i, b"zeroset binary")),
        ("solid_header.STL", writers::binary_stl(v, i, b"solid but binary")),
        ("ascii.stl", writers::ascii_stl(v, i)),
        ("mesh.off", writers::off(v, i)),
        ("mesh.glb", writers::glb(v, i)),
    ];
    let mut out = Vec::new();
    for (name, bytes) in files {
        let path = dir.join(name);
        writers::write(&path, &bytes);
        out.push(path);
    }
    let (json, bin) = writers::gltf_parts(v, i, r#"[{"mesh":0}]"#, Some("my%20data.bin"));
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    writers::write(&dir.join("sub/my data.bin"), &bin);
    writers::write(&dir.join("sub/mesh.gltf"), json.as_bytes());
    out.push(dir.join("sub/mesh.gltf"));
    out
}

#[test]
fn every_format_reads_the_plys_triangles_bit_for_bit() {
    let ply = icosphere();
    let dir = tempfile::tempdir().unwrap();
    for path in write_all(dir.path(), &ply) {
        let report = read_mesh_report(&path, None).unwrap();
        let d = &report.data;
        assert_eq!(d.indices.len(), 320, "{}", path.display());
        for t in 0..320 {
            assert_eq!(
                bits(corners(d, t)),
                bits(corners(&ply, t)),
                "{} triangle {t}",
                path.display()
            );
        }
        // welding gives back the PLY's 162 shared vertices: 960 corners, 798 merged
        assert_eq!(d.vertices.len(), 162, "{}", path.display());
        if path.extension().unwrap().eq_ignore_ascii_case("stl") {
            assert_eq!(report.merged_vertices, 960 - 162);
            let kind = if path.ends_with("ascii.stl") { "ASCII" } else { "binary" };
            assert_eq!(
                report.notes,
                [format!(
                    "STL ({kind}): 960 triangle corners welded into 162 vertices (798 merged)"
                )]
            );
        }
    }
}

/// The first hit of `mesh` along `ray`: `(t bits, triangle)`.
fn first(mesh: &Mesh, ray: &Ray) -> Option<(u64, u32)> {
    mesh.intersect(ray, Interval::POSITIVE)
        .map(|h| (h.t.to_bits(), h.feature))
}

fn random_ray(rng: &mut StdRng) -> Ray {
    let unit = |rng: &mut StdRng| {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        v.normalize_or(DVec3::X)
    };
    let o = unit(rng) * rng.random_range(0.0..3.0);
    let target = unit(rng) * rng.random_range(0.0..1.2);
    Ray::new(o, target - o)
}

#[test]
fn every_format_gives_the_plys_hits_on_random_rays() {
    let ply = icosphere();
    let reference = ply.clone().into_mesh(Path::new("ply"), false).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut rng = StdRng::seed_from_u64(45);
    let rays: Vec<Ray> = (0..20_000).map(|_| random_ray(&mut rng)).collect();
    let want: Vec<_> = rays.iter().map(|r| first(&reference, r)).collect();
    let hits = want.iter().filter(|h| h.is_some()).count();
    assert!(hits > 5_000, "{hits} hits");
    for path in write_all(dir.path(), &ply) {
        let mesh = load_mesh(&path, false).unwrap();
        let got: Vec<_> = rays.iter().map(|r| first(&mesh, r)).collect();
        let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{}: {differ} of {} rays differ", path.display(), rays.len());
    }
}

/// Distinct crossings along `ray` with the mesh's triangles (each a [`Triangle`], all tested):
/// crossings at one `t` (through a shared edge or vertex) count once, as `count_intersections`
/// counts them.
fn crossings(triangles: &[Triangle], ray: &Ray) -> usize {
    let mut ts: Vec<f64> = triangles
        .iter()
        .filter_map(|t| t.intersect(ray, Interval::POSITIVE).map(|h| h.t))
        .collect();
    ts.sort_by(f64::total_cmp);
    ts.dedup_by(|b, a| *b - *a <= 1e-9 * *b);
    ts.len()
}

#[test]
fn a_closed_binary_stl_is_watertight_at_its_welded_edges_and_vertices() {
    let ply = icosphere();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("closed.stl");
    writers::write(&path, &writers::binary_stl(&ply.vertices, &ply.indices, b""));
    let data = read_mesh(&path).unwrap();
    let mesh = data.clone().into_mesh(&path, false).unwrap();
    let triangles: Vec<Triangle> = (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c] = mesh.triangle(t);
            Triangle::new(a, b, c).unwrap()
        })
        .collect();
    let centre = data
        .vertices
        .iter()
        .map(|p| DVec3::from_array(p.map(f64::from)))
        .sum::<DVec3>()
        / data.vertices.len() as f64;
    let mut rng = StdRng::seed_from_u64(7);
    let (mut odd, mut rays, mut through) = (0, 0, 0);
    for k in 0..100_000 {
        // aim from outside at a vertex (¼) or a point of an edge (¾): the cracks welding closes
        let t = data.indices[rng.random_range(0..data.indices.len())];
        let p = |i: u32| DVec3::from_array(data.vertices[i as usize].map(f64::from));
        let target = if k % 4 == 0 {
            p(t[0])
        } else {
            let e = rng.random_range(0..3);
            let (a, b) = (p(t[e]), p(t[(e + 1) % 3]));
            a + rng.random::<f64>() * (b - a)
        };
        // through the target and a point near the centre (the star-shaped mesh's kernel): the
        // line enters and leaves exactly once
        let inner = centre
            + DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * 0.05;
        let o = inner + (target - inner) * rng.random_range(2.0..3.0);
        let n = crossings(&triangles, &Ray::new(o, inner - o));
        rays += 1;
        odd += n % 2;
        through += usize::from(n == 2);
    }
    println!("closed STL: {rays} rays from outside through welded edges/vertices, {odd} odd crossing counts, {through} through");
    assert_eq!(odd, 0);
    // every line through the kernel goes in and out: exactly two crossings
    assert_eq!(through, rays);
}

#[test]
fn stl_welding_merges_minus_zero_with_zero_and_keeps_the_first_bits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zeros.stl");
    let text = "solid z\nfacet normal 0 0 1\nouter loop\nvertex -0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n\
                facet normal 0 0 1\nouter loop\nvertex 0 -0 0\nvertex 0 -1 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid z\n";
    writers::write(&path, text.as_bytes());
    let report = read_mesh_report(&path, None).unwrap();
    assert_eq!(report.data.vertices.len(), 4);
    assert_eq!(report.merged_vertices, 2);
    assert_eq!(report.data.indices, [[0, 1, 2], [0, 3, 1]]);
    assert_eq!(report.data.vertices[0][0].to_bits(), (-0.0f32).to_bits());
}

#[test]
fn content_decides_where_the_extension_lies() {
    let ply = icosphere();
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "binary_named.STL",
            writers::binary_stl(&ply.vertices, &ply.indices, b"solid x"),
        ),
        ("a_glb.gltf", writers::glb(&ply.vertices, &ply.indices)),
        (
            "a_ply.stl",
            std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/icosphere2.ply")).unwrap(),
        ),
        ("a_glb_with_no_extension", writers::glb(&ply.vertices, &ply.indices)),
    ];
    for (name, bytes) in cases {
        let path = dir.path().join(name);
        writers::write(&path, &bytes);
        let d = read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(d.indices.len(), 320, "{name}");
        assert_eq!(bits(corners(&d, 17)), bits(corners(&ply, 17)), "{name}");
    }
}

/// A glTF JSON with `nodes` and `meshes`, one buffer (a data URI of `bin`), views and accessors.
fn gltf_json(nodes: &str, meshes: &str, bin: &[u8], views: &str, accessors: &str, scene_nodes: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":{scene_nodes}}}],"nodes":{nodes},"meshes":{meshes},
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}],"bufferViews":{views},"accessors":{accessors}}}"#,
        bin.len(),
        base64(bin)
    )
}

fn base64(b: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in b.chunks(3) {
        let n =
            (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k)) as usize & 63] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn gltf_node_transforms_compose_parent_then_child_in_f64() {
    let ply = icosphere();
    let dir = tempfile::tempdir().unwrap();
    // root: translate (10, 0, 0) after a half turn about z; child: column-major matrix scaling
    // by 2 then translating (0, 1, 0); so world(p) = (10 − 2x, −2y − 1, 2z)
    let nodes = r#"[{"name":"root","translation":[10,0,0],"rotation":[0,0,1,0],"children":[1]},
        {"name":"child","mesh":0,"matrix":[2,0,0,0, 0,2,0,0, 0,0,2,0, 0,1,0,1]}]"#;
    let (json, bin) = writers::gltf_parts(&ply.vertices, &ply.indices, nodes, None);
    let path = dir.path().join("placed.glb");
    writers::write(&path, &writers::glb_container(&json, &bin));
    let d = read_mesh(&path).unwrap();
    assert_eq!(d.indices, ply.indices);
    for (q, p) in d.vertices.iter().zip(&ply.vertices) {
        let p = p.map(f64::from);
        let want = [
            (10.0 - 2.0 * p[0]) as f32,
            (-2.0 * p[1] - 1.0) as f32,
            (2.0 * p[2]) as f32,
        ];
        assert_eq!(q.map(f32::to_bits), want.map(f32::to_bits));
    }
    // the same through `node:` in a scene, and the translation the scene's `matrix:` would give
    let scene_text = format!(
        "Scene(camera: (), objects: [(shape: Mesh(path: {:?}, node: \"child\"))])",
        path.display()
    );
    let context = BuildContext::new(dir.path());
    Scene::from_ron_in(&scene_text, "placed.ron", &context).unwrap();
    let err = Scene::from_ron(&scene_text.replace("\"child\"", "\"nobody\""), "placed.ron")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no node named \"nobody\"") && err.contains("\"root\""),
        "{err}"
    );
    let err = Scene::from_ron(
        &format!(
            "Scene(camera: (), objects: [(shape: Mesh(path: {:?}, node: \"x\"))])",
            dir.path().join("a.stl").display()
        ),
        "x.ron",
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("not a glTF file"), "{err}");
    // a mirror (scale −1 in x) reverses the winding, keeping the faces outward
    let (json, bin) = writers::gltf_parts(&ply.vertices, &ply.indices, r#"[{"mesh":0,"scale":[-1,1,1]}]"#, None);
    let path = dir.path().join("mirror.glb");
    writers::write(&path, &writers::glb_container(&json, &bin));
    let d = read_mesh(&path).unwrap();
    for (dt, pt) in d.indices.iter().zip(&ply.indices) {
        assert_eq!(*dt, [pt[0], pt[2], pt[1]]);
    }
    let outward = |d: &MeshData| {
        (0..d.indices.len())
            .filter(|&t| {
                let [a, b, c] = corners(d, t).map(|p| DVec3::from_array(p.map(f64::from)));
                (b - a).cross(c - a).dot(a + b + c) > 0.0
            })
            .count()
    };
    assert_eq!((outward(&ply), outward(&d)), (320, 320));
}

#[test]
fn gltf_strips_fans_points_selection_and_instancing() {
    // four positions of a unit square, five of a fan; indices for a strip of 4 and a fan of 5
    let square: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
    let mut bin = Vec::new();
    for p in square {
        for x in p {
            bin.extend(x.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 3, 0, 1, 3, 2] {
        bin.extend(i.to_le_bytes());
    }
    let views = r#"[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":16}]"#;
    let accessors = r#"[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
        {"bufferView":1,"componentType":5123,"count":4,"type":"SCALAR"},
        {"bufferView":1,"byteOffset":8,"componentType":5123,"count":4,"type":"SCALAR"}]"#;
    let meshes = r#"[{"name":"strip","primitives":[{"attributes":{"POSITION":0},"indices":1,"mode":5}]},
        {"name":"fan","primitives":[{"attributes":{"POSITION":0},"indices":2,"mode":6},{"attributes":{"POSITION":0},"mode":0}]}]"#;
    let nodes = r#"[{"name":"a","mesh":0},{"name":"b","mesh":1,"translation":[0,0,5]},{"name":"c","mesh":0,"translation":[0,0,9]}]"#;
    let json = gltf_json(nodes, meshes, &bin, views, accessors, "[0,1,2]");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("modes.gltf");
    writers::write(&path, json.as_bytes());
    let all = read_mesh_report(&path, None).unwrap();
    // nodes are walked from the last root: c (strip at z 9), b (fan at z 5), a (strip)
    assert_eq!(all.data.indices.len(), 6);
    assert_eq!(all.data.vertices.len(), 12);
    assert_eq!(
        all.notes,
        ["meshes[1].primitives[1] (nodes[1]): Points skipped (only triangles are ray cast)"]
    );
    // strip (0 1 2)(2 1 3); fan of (0 1 3 2): (0 1 3)(0 3 2); all counter-clockwise about +z
    let fan = read_mesh_report(&path, Some("b")).unwrap().data;
    assert_eq!(fan.indices, [[0, 1, 3], [0, 3, 2]]);
    assert!(fan.vertices.iter().all(|p| p[2] == 5.0));
    let strip = read_mesh_report(&path, Some("a")).unwrap().data;
    assert_eq!(strip.indices, [[0, 1, 2], [2, 1, 3]]);
    assert!(strip.vertices.iter().all(|p| p[2] == 0.0));
}

/// A malformed file and the words its error must contain (besides the path).
struct Bad {
    name: &'static str,
    bytes: Vec<u8>,
    needles: Vec<&'static str>,
    /// Files written beside it.
    extra: Vec<(&'static str, Vec<u8>)>,
}

fn bad(name: &'static str, bytes: impl Into<Vec<u8>>, needles: &[&'static str]) -> Bad {
    Bad {
        name,
        bytes: bytes.into(),
        needles: needles.to_vec(),
        extra: Vec::new(),
    }
}

fn set_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// Forty-odd malformed files across the four new formats.
fn malformed() -> Vec<Bad> {
    let ply = icosphere();
    let (v, i) = (&ply.vertices, &ply.indices);
    let stl = writers::binary_stl(v, i, b"bin");
    let with = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = stl.clone();
        f(&mut b);
        b
    };
    let ascii = String::from_utf8(writers::ascii_stl(v, &i[..4])).unwrap();
    let off = String::from_utf8(writers::off(&v[..4], &[[0, 1, 2], [0, 2, 3]])).unwrap();
    let off_body = "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n";
    let (json, bin) = writers::gltf_parts(v, i, r#"[{"mesh":0}]"#, None);
    let glb_json = |from: &str, to: &str| {
        assert!(json.contains(from), "{from}");
        writers::glb_container(&json.replacen(from, to, 1), &bin)
    };
    let glb_bin = |at: usize, value: &[u8]| {
        let mut b = bin.clone();
        b[at..at + value.len()].copy_from_slice(value);
        writers::glb_container(&json, &b)
    };
    let glb = writers::glb(v, i);
    let long_line = format!(
        "solid x\n{}\n",
        "f".repeat(zeroset::scene::mesh_io::MAX_LINE_BYTES + 10)
    );
    let vbytes = 12 * v.len();
    let list = vec![
        // binary STL
        bad(
            "truncated.stl",
            &stl[..stl.len() - 10],
            &["binary STL", "triangle 319 at byte 16034", "cut off"],
        ),
        bad(
            "count_2e31.stl",
            with(&|b| set_u32(b, 80, 1 << 31)),
            &["byte 80", "2147483648 triangles"],
        ),
        bad(
            "count_max.stl",
            with(&|b| set_u32(b, 80, u32::MAX)),
            &["4294967295 triangles"],
        ),
        bad(
            "count_one_more.stl",
            with(&|b| set_u32(b, 80, 321)),
            &["triangle 320 at byte 16084"],
        ),
        bad(
            "count_one_less.stl",
            with(&|b| set_u32(b, 80, 319)),
            &["50 bytes follow the last triangle"],
        ),
        bad(
            "nan.stl",
            with(&|b| b[84 + 250 + 24..84 + 250 + 28].copy_from_slice(&f32::NAN.to_le_bytes())),
            &["triangle 5 at byte 334", "corner 1", "not finite"],
        ),
        bad(
            "inf.stl",
            with(&|b| b[84 + 12..84 + 16].copy_from_slice(&f32::INFINITY.to_le_bytes())),
            &["triangle 0 at byte 84", "corner 0"],
        ),
        bad("short.stl", &stl[..40], &["40 bytes", "84-byte header"]),
        bad("empty.stl", Vec::new(), &["0 bytes", "84-byte header"]),
        bad("zero_count.stl", &stl[..84], &["0 triangles"]).with_count_zero(),
        // ASCII STL
        bad(
            "truncated_ascii.stl",
            &ascii.as_bytes()[..ascii.match_indices("outer loop\n").nth(2).unwrap().0 + 11],
            &["ASCII STL", "line 18", "unexpected end of file inside facet 2"],
        ),
        bad(
            "missing_z.stl",
            replace_vertex(&ascii, 2, "1 2"),
            &["line 6", "facet 0, vertex 2", "coordinate z: missing"],
        ),
        bad(
            "nan_ascii.stl",
            replace_vertex(&ascii, 1, "nan 0 0"),
            &["line 5", "facet 0, vertex 1", "`nan` is not finite"],
        ),
        bad(
            "word_ascii.stl",
            replace_vertex(&ascii, 0, "1 2 abc"),
            &["line 4", "`abc` is not a number"],
        ),
        bad(
            "four_vertices.stl",
            ascii.replacen("    endloop", "      vertex 0 0 0\n    endloop", 1),
            &["line 7", "expected `endloop`"],
        ),
        bad(
            "no_loop.stl",
            ascii.replacen("    outer loop\n", "", 1),
            &["line 3", "expected `outer loop`"],
        ),
        bad(
            "garbage.stl",
            "solid x\nhello world\n",
            &["line 2", "expected `facet normal` or `endsolid`", "hello"],
        ),
        bad("long_line.stl", long_line, &["line 2", "longer than"]),
        bad(
            "not_utf8.stl",
            b"solid x\n\xff\xfe\x00 facet\n".to_vec(),
            &["line 2", "invalid UTF-8"],
        ),
        bad("no_facets.stl", "solid x\nendsolid x\n", &["no facets"]),
        bad(
            "no_endsolid.stl",
            ascii.replace("endsolid zeroset\n", ""),
            &["unexpected end of file inside facet 4"],
        ),
        // OFF
        bad(
            "magic.off",
            off.replacen("OFF", "OFX", 1),
            &["line 1 (byte 0)", "expected the keyword `OFF`"],
        ),
        bad(
            "lying_counts.off",
            "OFF\n1000000000 1 0\n0 0 0\n",
            &["line 2", "1000000000 vertices", "but the file has"],
        ),
        bad(
            "lying_faces.off",
            "OFF\n3 4000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            &["4000000000 faces"],
        ),
        bad(
            "truncated.off",
            &off.as_bytes()[..off.len() - 8],
            &["unexpected end of file at face 1", "line 9"],
        ),
        bad(
            "bad_index.off",
            format!("{off_body}3 0 1 7\n3 0 2 3\n"),
            &["line 7", "face 0", "vertex index 7 out of range (4 vertices)"],
        ),
        bad(
            "negative_index.off",
            format!("{off_body}3 0 1 2\n3 0 -1 3\n"),
            &["line 8", "face 1", "vertex index -1"],
        ),
        bad(
            "two_index_face.off",
            format!("{off_body}2 0 1\n3 0 2 3\n"),
            &["line 7", "face 0", "at least 3"],
        ),
        bad(
            "nan.off",
            off_body.replacen("1 0 0", "1 nan 0", 1) + "3 0 1 2\n3 0 2 3\n",
            &["line 4", "vertex 1", "not finite"],
        ),
        bad(
            "missing_y.off",
            off_body.replacen("0 1 0", "0", 1) + "3 0 1 2\n3 0 2 3\n",
            &["line 5", "vertex 2", "y: missing"],
        ),
        bad(
            "short_face.off",
            format!("{off_body}4 0 1 2\n3 0 2 3\n"),
            &["line 7", "4 vertices announced, 3 given"],
        ),
        bad(
            "dimension.off",
            "4OFF\n1 1 0\n0 0 0 0\n3 0 0 0\n",
            &["line 1", "dimension"],
        ),
        bad("binary.off", "OFF BINARY\n", &["line 1", "binary OFF"]),
        bad("counts.off", "OFF\nx y z\n", &["line 2", "vertex count `x`"]),
        bad("empty.off", "", &["line 1", "end of file in the header"]),
        // GLB and glTF
        bad(
            "version.glb",
            {
                let mut b = glb.clone();
                set_u32(&mut b, 4, 3);
                b
            },
            &["GLB", "byte 4", "version 3"],
        ),
        bad("truncated.glb", &glb[..glb.len() - 100], &["byte 8", "the header says"]),
        bad(
            "chunk_length.glb",
            {
                let mut b = glb.clone();
                set_u32(&mut b, 12, 1 << 30);
                b
            },
            &["byte 12", "chunk 0 claims 1073741824 bytes"],
        ),
        bad(
            "count_lie.glb",
            glb_json(r#""count":162"#, r#""count":2147483647"#),
            &["accessors[0] (POSITION)", "2147483647 elements", "bufferViews[0]"],
        ),
        bad(
            "index_range.glb",
            glb_bin(vbytes + 4 * 7, &9999u32.to_le_bytes()),
            &[
                "meshes[0].primitives[0]",
                "index 7 is 9999, out of range (162 positions)",
            ],
        ),
        bad(
            "nan.glb",
            glb_bin(12 * 3 + 4, &f32::NAN.to_le_bytes()),
            &["accessors[0] (POSITION): element 3", "not finite"],
        ),
        bad(
            "quantized.glb",
            glb_json(
                r#""asset""#,
                r#""extensionsRequired":["KHR_mesh_quantization"],"extensionsUsed":["KHR_mesh_quantization"],"asset""#,
            ),
            &["KHR_mesh_quantization"],
        ),
        bad(
            "short_position.glb",
            glb_json(r#""componentType":5126"#, r#""componentType":5123"#),
            &["accessors[0] (POSITION)", "VEC3 of FLOAT"],
        ),
        bad(
            "sparse.glb",
            glb_json(
                r#""count":162,"#,
                r#""count":162,"sparse":{"count":1,"indices":{"bufferView":1,"componentType":5125},"values":{"bufferView":0}},"#,
            ),
            &["accessors[0] (POSITION)", "sparse"],
        ),
        bad(
            "view_past_buffer.glb",
            glb_json(
                r#""byteOffset":0,"byteLength":1944"#,
                r#""byteOffset":4000,"byteLength":1944"#,
            ),
            &["bufferViews[0] spans bytes 4000..5944"],
        ),
        bad(
            "bad_reference.glb",
            glb_json(r#""bufferView":1,"#, r#""bufferView":9,"#),
            &["invalid", "accessors[1].bufferView"],
        ),
        bad(
            "json_syntax.gltf",
            "{\"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [oops]}",
            &["glTF JSON", "line 2"],
        ),
        bad(
            "wrong_magic.glb",
            {
                let mut b = glb.clone();
                b[3] = b'X';
                b
            },
            &["glTF JSON", "line 1 column 1"],
        ),
        Bad {
            ..bad(
                "missing_bin.gltf",
                json.replacen(r#""byteLength":5784"#, r#""byteLength":5784,"uri":"gone.bin""#, 1),
                &["buffers[0]", "gone.bin"],
            )
        },
        Bad {
            extra: vec![("short.bin", bin[..1000].to_vec())],
            ..bad(
                "short_bin.gltf",
                json.replacen(r#""byteLength":5784"#, r#""byteLength":5784,"uri":"short.bin""#, 1),
                &["buffers[0]", "short.bin", "byteLength 5784, the file has 1000 bytes"],
            )
        },
    ];
    list
}

trait CountZero {
    fn with_count_zero(self) -> Self;
}

impl CountZero for Bad {
    /// The 84-byte header alone with a count of 0.
    fn with_count_zero(mut self) -> Self {
        set_u32(&mut self.bytes, 80, 0);
        self
    }
}

/// The ASCII STL `text` with its `k`-th `vertex` line's coordinates replaced.
fn replace_vertex(text: &str, k: usize, coords: &str) -> String {
    let mut seen = 0;
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with("vertex") {
                seen += 1;
                if seen == k + 1 {
                    return format!("      vertex {coords}\n");
                }
            }
            format!("{l}\n")
        })
        .collect()
}

fn write_bad(dir: &Path, b: &Bad) -> PathBuf {
    for (name, bytes) in &b.extra {
        writers::write(&dir.join(name), bytes);
    }
    let path = dir.join(b.name);
    writers::write(&path, &b.bytes);
    path
}

#[test]
fn forty_malformed_files_are_refused_with_their_place_named() {
    let dir = tempfile::tempdir().unwrap();
    let list = malformed();
    assert!(list.len() >= 40, "{} files", list.len());
    let mut per_format = std::collections::BTreeMap::new();
    for b in &list {
        let path = write_bad(dir.path(), b);
        let message = match load_mesh(&path, true) {
            Ok(_) => panic!("{}: loaded", b.name),
            Err(e) => e.to_string(),
        };
        assert!(message.starts_with(&format!("{}: ", path.display())), "{message}");
        for needle in &b.needles {
            assert!(message.contains(needle), "{}: `{needle}` not in: {message}", b.name);
        }
        *per_format
            .entry(path.extension().unwrap().to_string_lossy().to_string())
            .or_insert(0) += 1;
    }
    println!("{} malformed files refused: {per_format:?}", list.len());
}

#[test]
fn malformed_files_are_refused_without_abort_under_a_2_gb_address_space() {
    if std::process::Command::new("prlimit").arg("--version").output().is_err() {
        eprintln!("prlimit not found: skipped");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.csv");
    writers::write(&rays, b"0,0,-5,0,0,1\n");
    let list = malformed();
    for b in &list {
        let path = write_bad(dir.path(), b);
        let scene = dir.path().join(format!("{}.ron", b.name));
        writers::write(
            &scene,
            format!("Scene(camera: (), objects: [(shape: Mesh(path: {:?}))])", b.name).as_bytes(),
        );
        let out = std::process::Command::new("prlimit")
            .arg("--as=2147483648")
            .arg("--")
            .arg(env!("CARGO_BIN_EXE_zeroset"))
            .args(["query", "--threads", "1", "--rays"])
            .arg(&rays)
            .arg(&scene)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        // a refusal: an ordinary error exit (not a panic's 101, not a signal such as SIGABRT)
        assert!(
            matches!(out.status.code(), Some(c) if c != 0 && c != 101),
            "{}: {:?}\n{stderr}",
            b.name,
            out.status
        );
        assert!(
            stderr.contains(&path.display().to_string()) && !stderr.contains("panicked"),
            "{}: {stderr}",
            b.name
        );
    }
}

#[test]
fn each_example_format_scene_loads_with_its_notes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let path = root.join("mesh_formats.ron");
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.objects.len(), 6);
    let merged = scene.warnings.iter().filter(|w| w.contains("welded into")).count();
    assert_eq!(merged, 2, "{:?}", scene.warnings);
    for name in [
        "icosphere2.stl",
        "icosphere2_ascii.stl",
        "icosphere2.off",
        "icosphere2.glb",
    ] {
        let file = root.join("meshes").join(name);
        assert!(std::fs::metadata(&file).unwrap().len() < 100_000, "{name}");
        let d = read_mesh(&file).unwrap();
        assert_eq!((d.indices.len(), d.vertices.len()), (320, 162), "{name}");
    }
}

#[test]
fn degenerate_stl_and_off_triangles_are_counted_and_skipped_as_for_ply() {
    let ply = icosphere();
    let dir = tempfile::tempdir().unwrap();
    let mut indices = ply.indices.clone();
    // a triangle with two equal corners (welded into one vertex) and a collinear one
    indices.push([0, 0, 5]);
    indices.push([0, 0, 0]);
    writers::write(
        &dir.path().join("d.stl"),
        &writers::binary_stl(&ply.vertices, &indices, b""),
    );
    writers::write(&dir.path().join("d.off"), &writers::off(&ply.vertices, &indices));
    for name in ["d.stl", "d.off"] {
        let text = format!("Scene(camera: (), objects: [(shape: Mesh(path: {name:?}))])");
        let context = BuildContext::new(dir.path());
        let scene = Scene::from_ron_in(&text, "d.ron", &context).unwrap();
        assert!(
            scene
                .warnings
                .iter()
                .any(|w| w.contains("2 of 322 triangles are degenerate")),
            "{name}: {:?}",
            scene.warnings
        );
    }
}
