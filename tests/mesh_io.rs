//! Mesh files and mesh scenes: the three formats load the same triangles; malformed files give
//! errors naming the file; a scene with a mesh instanced three times renders and shares one mesh.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use zeroset::aov::Aov;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::mesh_io::{load_mesh, read_mesh, read_ply_generic, MeshDesc};
use zeroset::scene::registry::{BuildContext, SceneShape};
use zeroset::scene::Scene;

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

fn corners(data: &zeroset::scene::mesh_io::MeshData, t: usize) -> [[f32; 3]; 3] {
    data.indices[t].map(|i| data.vertices[i as usize])
}

#[test]
fn obj_ascii_ply_and_binary_ply_load_the_same_triangles() {
    let dir = scenes().join("meshes");
    let obj = read_mesh(&dir.join("icosphere2.obj")).unwrap();
    let ascii = read_mesh(&dir.join("icosphere2_ascii.ply")).unwrap();
    let binary = read_mesh(&dir.join("icosphere2.ply")).unwrap();
    assert_eq!(binary.indices.len(), 320);
    let mut max_diff = 0f32;
    for other in [&obj, &ascii] {
        assert_eq!(other.indices.len(), binary.indices.len());
        assert!(other.normals.is_some());
        for t in 0..binary.indices.len() {
            for (p, q) in corners(other, t).iter().zip(corners(&binary, t)) {
                for k in 0..3 {
                    max_diff = max_diff.max((p[k] - q[k]).abs());
                }
            }
        }
    }
    assert!(binary.normals.is_some());
    // the files hold 8–9 significant digits
    assert!(max_diff < 1e-6, "max coordinate difference {max_diff}");
    let mesh = load_mesh(&dir.join("icosphere2.ply"), true).unwrap();
    assert_eq!(mesh.triangle_count(), 320);
    assert!(mesh.has_normals());
}

fn expect_error(name: &str, contents: &[u8], needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, contents).unwrap();
    let message = load_mesh(&path, true).unwrap_err().to_string();
    assert!(message.contains(&path.display().to_string()), "{message}");
    for needle in needles {
        assert!(message.contains(needle), "`{needle}` not in: {message}");
    }
}

const ASCII_HEADER: &str =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

#[test]
fn malformed_files_give_errors_naming_the_file() {
    expect_error(
        "bad_index.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        &["out of bounds"],
    );
    expect_error(
        "nan.obj",
        b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        &["vertices[0]", "finite"],
    );
    expect_error(
        "bad_index.ply",
        format!("{ASCII_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n").as_bytes(),
        &["face 0", "vertex index 7"],
    );
    // ply-rs rejects a `nan` token in an ASCII file itself (naming the element and line)
    expect_error(
        "nan_ascii.ply",
        format!("{ASCII_HEADER}0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n").as_bytes(),
        &["element `vertex`", "Line"],
    );
    let mut nan_binary = ASCII_HEADER.replace("ascii", "binary_little_endian").into_bytes();
    for x in [0.0f32, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, 1.0, 0.0] {
        nan_binary.extend(x.to_le_bytes());
    }
    nan_binary.push(3);
    for i in [0i32, 1, 2] {
        nan_binary.extend(i.to_le_bytes());
    }
    expect_error("nan_binary.ply", &nan_binary, &["vertex 1", "not finite"]);
    let binary = std::fs::read(scenes().join("meshes/icosphere2.ply")).unwrap();
    expect_error(
        "truncated.ply",
        &binary[..binary.len() - 1000],
        &["element `face`", "end of file"],
    );
    expect_error("not_a_mesh.xyz", b"solid", &["unknown mesh format"]);
    for missing in ["missing.ply", "missing.obj"] {
        let path = Path::new("/nonexistent/dir").join(missing);
        let message = load_mesh(&path, true).unwrap_err().to_string();
        assert!(
            message.contains("/nonexistent/dir/") && message.contains(missing),
            "{message}"
        );
    }
    // through a scene: file, object and mesh path in one message
    let err = Scene::from_ron(
        "Scene(camera: (), objects: [(name: \"m\", shape: Mesh(path: \"/nonexistent/x.ply\"))])",
        "inline.ron",
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("inline.ron") && err.contains("/nonexistent/x.ply"),
        "{err}"
    );
}

#[test]
fn instanced_mesh_scene_renders_and_shares_one_mesh() {
    let path = scenes().join("mesh.ron");
    let context = BuildContext::new(scenes());
    let scene = Scene::from_ron_in(&std::fs::read_to_string(&path).unwrap(), "mesh.ron", &context).unwrap();
    {
        let loaded = context.loaded.lock().unwrap();
        // one copy with normals (two objects), one without (one object)
        assert_eq!(loaded.len(), 2);
        let with_normals = loaded.get(&scenes().join("meshes/icosphere2.ply")).unwrap();
        assert_eq!(Arc::strong_count(with_normals), 3);
    }
    // building the description again reuses the loaded mesh
    let desc = MeshDesc {
        path: "meshes/icosphere2.ply".into(),
        normals: true,
        node: None,
    };
    assert!(Arc::ptr_eq(
        &desc.build(&context).unwrap(),
        &desc.build(&context).unwrap()
    ));

    let options = RenderOptions {
        aovs: vec![Aov::PrimitiveId, Aov::Normal, Aov::ShadingNormal],
        ..RenderOptions::default()
    };
    let frame = render(&scene, &options);
    let (mut seen, mut differ) = ([0usize; 4], [0usize; 4]);
    for y in 0..frame.height {
        for x in 0..frame.width {
            let id = frame.pixel(Aov::PrimitiveId, x, y).unwrap()[0];
            if !(0.0..3.0).contains(&id) {
                continue;
            }
            let id = id as usize;
            let n = frame.pixel(Aov::Normal, x, y).unwrap();
            let s = frame.pixel(Aov::ShadingNormal, x, y).unwrap();
            let len = |v: &[f32]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((len(n) - 1.0).abs() < 1e-5 && (len(s) - 1.0).abs() < 1e-5);
            seen[id] += 1;
            if n.iter().zip(s).any(|(a, b)| (a - b).abs() > 1e-4) {
                differ[id] += 1;
            }
        }
    }
    assert!(seen[0] > 500 && seen[1] > 500 && seen[2] > 200, "{seen:?}");
    // interpolated normals differ from face normals on the two objects that use them
    assert!(
        differ[0] * 2 > seen[0] && differ[1] * 2 > seen[1],
        "{differ:?} of {seen:?}"
    );
    // `normals: false`: the shading normal is the geometric one
    assert_eq!(differ[2], 0);
}

#[test]
fn binary_ply_decoder_matches_the_ply_rs_path() {
    let path = scenes().join("meshes/icosphere2.ply");
    let fast = read_mesh(&path).unwrap();
    let generic = read_ply_generic(&path).unwrap();
    assert_eq!(fast.vertices.len(), 162);
    assert_eq!(fast.indices.len(), 320);
    assert_eq!(fast.normals.as_ref().map(Vec::len), Some(162));
    assert_eq!(fast, generic);
    // the ASCII file holds the same mesh to 8–9 digits
    let ascii = read_mesh(&scenes().join("meshes/icosphere2_ascii.ply")).unwrap();
    assert_eq!(ascii.indices, fast.indices);
    assert_eq!(&fast.indices[..2], &[[0, 137, 53], [137, 37, 139]]);
    let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-7);
    assert!(close(fast.vertices[0], [-0.525_731_1, 0.850_650_8, 0.0]));
    assert!(close(
        fast.normals.unwrap()[161],
        [-0.912_887_3, -0.298_455_7, 0.278_497_8]
    ));
}

/// Writes `contents` to a temporary `name` and reads it with both PLY readers.
fn read_both(name: &str, contents: &[u8]) -> (zeroset::scene::mesh_io::MeshData, zeroset::scene::mesh_io::MeshData) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, contents).unwrap();
    (read_mesh(&path).unwrap(), read_ply_generic(&path).unwrap())
}

#[test]
fn big_endian_ply_with_doubles_normals_extra_properties_and_polygons() {
    let header = "ply\nformat binary_big_endian 1.0\ncomment generated\n\
        element vertex 5\nproperty double x\nproperty double y\nproperty double z\nproperty uchar flags\n\
        property double nx\nproperty double ny\nproperty double nz\n\
        element material 2\nproperty list uchar float weights\nproperty int id\n\
        element face 3\nproperty uchar tag\nproperty list ushort uint vertex_indices\nproperty list uchar short extra\n\
        element edge 1\nproperty list int uchar ends\n\
        end_header\n";
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, -0.5],
        [0.1, 0.5, 2.25],
    ];
    let normals = [
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.6, 0.8, 0.0],
        [0.0, -0.6, 0.8],
    ];
    let mut file = header.as_bytes().to_vec();
    for (k, (p, n)) in positions.iter().zip(&normals).enumerate() {
        p.iter().for_each(|x: &f64| file.extend(x.to_be_bytes()));
        file.push(200 + k as u8);
        n.iter().for_each(|x: &f64| file.extend(x.to_be_bytes()));
    }
    for (weights, id) in [(&[0.5f32, 0.25][..], 7i32), (&[][..], -1)] {
        file.push(weights.len() as u8);
        weights.iter().for_each(|w| file.extend(w.to_be_bytes()));
        file.extend(id.to_be_bytes());
    }
    let faces: [&[u32]; 3] = [&[0, 1, 2], &[0, 1, 2, 3], &[4, 0, 1, 2, 3]];
    for (f, face) in faces.iter().enumerate() {
        file.push(f as u8);
        file.extend((face.len() as u16).to_be_bytes());
        face.iter().for_each(|i| file.extend(i.to_be_bytes()));
        file.push(f as u8);
        (0..f as i16).for_each(|e| file.extend((-e).to_be_bytes()));
    }
    file.extend(2i32.to_be_bytes());
    file.extend([0u8, 4]);

    let (fast, generic) = read_both("big_endian.ply", &file);
    let f32s = |v: &[[f64; 3]]| v.iter().map(|p| p.map(|x| x as f32)).collect::<Vec<_>>();
    assert_eq!(fast.vertices, f32s(&positions));
    assert_eq!(fast.vertices[4], [0.1f32, 0.5, 2.25]);
    assert_eq!(fast.normals, Some(f32s(&normals)));
    assert_eq!(
        fast.indices,
        vec![[0, 1, 2], [0, 1, 2], [0, 2, 3], [4, 0, 1], [4, 1, 2], [4, 2, 3]]
    );
    assert_eq!(fast, generic);
}

#[test]
fn little_endian_ply_with_integer_coordinates_and_indices() {
    // x short, y uchar, z int; no normals; `vertex_index` with a char count and ushort items
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty short x\nproperty uchar y\n\
        property int z\nproperty float nx\nelement face 2\nproperty list char ushort vertex_index\nend_header\n";
    let mut file = header.as_bytes().to_vec();
    for (x, y, z) in [(-3i16, 0u8, 70000i32), (5, 255, -2), (0, 1, 0), (1000, 9, 16777217)] {
        file.extend(x.to_le_bytes());
        file.push(y);
        file.extend(z.to_le_bytes());
        file.extend(0.5f32.to_le_bytes());
    }
    for face in [&[3u16, 2, 1, 0][..], &[0, 1, 2]] {
        file.push(face.len() as u8);
        face.iter().for_each(|i| file.extend(i.to_le_bytes()));
    }
    let (fast, generic) = read_both("integers.ply", &file);
    assert_eq!(
        fast.vertices,
        vec![
            [-3.0, 0.0, 70000.0],
            [5.0, 255.0, -2.0],
            [0.0, 1.0, 0.0],
            [1000.0, 9.0, 16777216.0]
        ]
    );
    assert_eq!(fast.normals, None);
    assert_eq!(fast.indices, vec![[3, 2, 1], [3, 1, 0], [0, 1, 2]]);
    assert_eq!(fast, generic);
}

#[test]
fn hostile_binary_ply_headers_give_errors_naming_the_element() {
    let le = "ply\nformat binary_little_endian 1.0\n";
    let xyz = "property float x\nproperty float y\nproperty float z\n";
    let face = "property list uchar int vertex_indices\n";
    let triangle = {
        let mut t = vec![3u8];
        [0i32, 1, 2].iter().for_each(|i| t.extend(i.to_le_bytes()));
        t
    };
    let vertices = |n: usize| (0..3 * n).flat_map(|k| (k as f32).to_le_bytes()).collect::<Vec<u8>>();
    let file = |header: String, payload: &[&[u8]]| [header.as_bytes(), &payload.concat()].concat();
    let truncated = "unexpected end of file (truncated?)";

    // huge counts
    let huge = 1_000_000_000_000_000_000usize;
    expect_error(
        "huge_vertices.ply",
        &file(
            format!("{le}element vertex {huge}\n{xyz}element face 1\n{face}end_header\n"),
            &[&vertices(3), &triangle],
        ),
        &["element `vertex`", truncated],
    );
    expect_error(
        "huge_faces.ply",
        &file(
            format!("{le}element vertex 3\n{xyz}element face {huge}\n{face}end_header\n"),
            &[&vertices(3), &triangle],
        ),
        &["element `face`", truncated],
    );
    expect_error(
        "huge_other.ply",
        &file(
            format!("{le}element vertex 3\n{xyz}element junk {huge}\nproperty list uint double v\nelement face 1\n{face}end_header\n"),
            &[&vertices(3), &[1, 0, 0, 0], &triangle],
        ),
        &["element `junk`", truncated],
    );
    // a list longer than the file
    expect_error(
        "huge_list.ply",
        &file(
            format!("{le}element vertex 3\n{xyz}element face 1\nproperty list uint int vertex_indices\nend_header\n"),
            &[&vertices(3), &u32::MAX.to_le_bytes(), &[0; 12]],
        ),
        &["element `face`", truncated],
    );
    // a vertex element with no properties: the first vertex has no position
    expect_error(
        "no_properties.ply",
        &file(
            format!("{le}element vertex {huge}\nelement face 0\n{face}end_header\n"),
            &[],
        ),
        &["vertex 0: position [NaN, NaN, NaN] is not finite (or x, y, z missing)"],
    );
    // missing z
    expect_error(
        "no_z.ply",
        &file(
            format!("{le}element vertex 1\nproperty float x\nproperty float y\nelement face 0\n{face}end_header\n"),
            &[&[0, 0, 128, 63, 0, 0, 0, 64]],
        ),
        &["vertex 0: position [1.0, 2.0, NaN] is not finite (or x, y, z missing)"],
    );
    // cut inside the vertex block, and inside a face's list
    let header = format!("{le}element vertex 3\n{xyz}element face 1\n{face}end_header\n");
    expect_error(
        "cut_vertices.ply",
        &file(header.clone(), &[&vertices(3)[..30]]),
        &["element `vertex`", truncated],
    );
    expect_error(
        "cut_face.ply",
        &file(header.clone(), &[&vertices(3), &triangle[..7]]),
        &["element `face`", truncated],
    );
    // a list length of type float, negative list lengths
    expect_error(
        "float_length.ply",
        &file(
            format!("{le}element vertex 3\n{xyz}element face 1\nproperty list float int vertex_indices\nend_header\n"),
            &[&vertices(3), &3f32.to_le_bytes(), &triangle[1..]],
        ),
        &["element `face`", "not an integer type"],
    );
    expect_error(
        "negative_length.ply",
        &file(
            format!("{le}element vertex 3\n{xyz}element face 1\nproperty list char int vertex_indices\nend_header\n"),
            &[&vertices(3), &[0xfd], &triangle[1..]],
        ),
        &["element `face`", "negative"],
    );
    // face errors, in the current wording
    let with_faces = |faces: &[u8]| file(header.clone(), &[&vertices(3), faces]);
    expect_error(
        "two_indices.ply",
        &with_faces(&[2, 0, 0, 0, 0, 1, 0, 0, 0]),
        &["face 0: 2 vertex indices"],
    );
    let mut bad = triangle.clone();
    bad[5..9].copy_from_slice(&(-1i32).to_le_bytes());
    expect_error(
        "negative_index.ply",
        &with_faces(&bad),
        &["face 0: vertex index -1 out of range (3 vertices)"],
    );
    let missing = |element: &str, header: String| {
        expect_error(
            &format!("no_{element}.ply"),
            &file(header, &[&vertices(3)]),
            &[&format!("no `{element}` element")],
        )
    };
    missing("face", format!("{le}element vertex 3\n{xyz}end_header\n"));
    missing("vertex", format!("{le}element points 3\n{xyz}end_header\n"));
}

/// One scalar of PLY type `ty` holding `v` (cast), in the given byte order.
fn ply_scalar(ty: &str, v: f64, big: bool) -> Vec<u8> {
    macro_rules! bytes {
        ($x:expr) => {
            if big {
                $x.to_be_bytes().to_vec()
            } else {
                $x.to_le_bytes().to_vec()
            }
        };
    }
    match ty {
        "char" => bytes!(v as i8),
        "uchar" => bytes!(v as u8),
        "short" => bytes!(v as i16),
        "ushort" => bytes!(v as u16),
        "int" => bytes!(v as i32),
        "uint" => bytes!(v as u32),
        "float" => bytes!(v as f32),
        _ => bytes!(v),
    }
}

#[test]
fn random_binary_plys_read_the_same_through_both_readers() {
    use rand::{Rng, SeedableRng};
    const TYPES: [&str; 8] = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double"];
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let dir = tempfile::tempdir().unwrap();
    let (mut ok, mut failed) = (0, 0);
    for case in 0..300 {
        let big = rng.random_bool(0.5);
        let nv = rng.random_range(0..6usize);
        let nf = rng.random_range(0..6usize);
        // properties: (name, count type for a list, item type)
        let mut vertex: Vec<(String, Option<&str>, &str)> = Vec::new();
        for name in ["x", "y", "z", "nx", "ny", "nz", "s", "t"] {
            if rng.random_bool(0.85) {
                vertex.push((name.into(), None, TYPES[rng.random_range(0..8)]));
            }
        }
        if rng.random_bool(0.2) {
            vertex.insert(
                rng.random_range(0..=vertex.len()),
                ("ring".into(), Some("uchar"), "short"),
            );
        }
        let index_name = ["vertex_indices", "vertex_index"][rng.random_range(0..2)];
        let types = |rng: &mut rand::rngs::StdRng, p| if rng.random_bool(p) { 8 } else { 6 };
        let n = types(&mut rng, 0.03);
        let count_type = TYPES[rng.random_range(0..n)];
        let n = types(&mut rng, 0.05);
        let item_type = TYPES[rng.random_range(0..n)];
        let mut face: Vec<(String, Option<&str>, &str)> = vec![(index_name.into(), Some(count_type), item_type)];
        if rng.random_bool(0.3) {
            face.insert(
                rng.random_range(0..2),
                ("flags".into(), None, TYPES[rng.random_range(0..8)]),
            );
        }
        if rng.random_bool(0.3) {
            face.push(("uv".into(), Some("uint"), "float"));
        }
        let junk = vec![("w".to_string(), Some("ushort"), "double"), ("k".into(), None, "int")];
        let mut elements = vec![("vertex", nv, vertex), ("face", nf, face)];
        if rng.random_bool(0.3) {
            elements.insert(rng.random_range(0..3), ("junk", rng.random_range(0..3), junk));
        }
        let format = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut file = format!("ply\nformat {format} 1.0\n");
        for (name, count, props) in &elements {
            file += &format!("element {name} {count}\n");
            for (p, list, ty) in props {
                match list {
                    Some(c) => file += &format!("property list {c} {ty} {p}\n"),
                    None => file += &format!("property {ty} {p}\n"),
                }
            }
        }
        let mut file = (file + "end_header\n").into_bytes();
        let header = file.len();
        for (name, count, props) in &elements {
            for _ in 0..*count {
                for (p, list, ty) in props {
                    let value = |rng: &mut rand::rngs::StdRng| match *name {
                        "vertex" if p == "x" && rng.random_bool(0.03) => f64::NAN,
                        "face" => {
                            let end = nv as i64 + i64::from(rng.random_bool(0.05));
                            rng.random_range(-1..end) as f64
                        }
                        _ => f64::from(rng.random_range(0..100u8)) - 20.0,
                    };
                    let Some(c) = list else {
                        let v = value(&mut rng);
                        file.extend(ply_scalar(ty, v, big));
                        continue;
                    };
                    let n = if *name == "face" && rng.random_bool(0.95) {
                        rng.random_range(3..7)
                    } else {
                        rng.random_range(0..4)
                    };
                    file.extend(ply_scalar(c, f64::from(n), big));
                    for _ in 0..n {
                        let v = value(&mut rng);
                        file.extend(ply_scalar(ty, v, big));
                    }
                }
            }
        }
        if rng.random_bool(0.15) {
            file.truncate(rng.random_range(header..file.len().max(header + 1)));
        }
        let path = dir.path().join(format!("random{case}.ply"));
        std::fs::write(&path, &file).unwrap();
        match (read_mesh(&path), read_ply_generic(&path)) {
            (Ok(fast), Ok(generic)) => {
                assert_eq!(fast, generic, "case {case}");
                ok += 1;
            }
            (Err(fast), Err(generic)) => {
                let (fast, generic) = (fast.to_string(), generic.to_string());
                let element = |m: &str| m.split('`').nth(1).map(str::to_owned);
                if generic.contains("expected): ") {
                    // a payload error: the same element, each reader with its own detail
                    assert_eq!(element(&fast), element(&generic), "case {case}: {fast} / {generic}");
                    assert_eq!(
                        fast.contains("truncated?"),
                        generic.contains("truncated?"),
                        "{fast} / {generic}"
                    );
                } else {
                    assert_eq!(fast, generic, "case {case}");
                }
                failed += 1;
            }
            (fast, generic) => panic!("case {case}: {fast:?} / {generic:?}"),
        }
    }
    // both outcomes are exercised
    assert!(ok > 50 && failed > 50, "{ok} read, {failed} failed");
}
