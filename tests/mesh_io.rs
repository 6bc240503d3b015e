//! Mesh files and mesh scenes: the three formats load the same triangles; malformed files give
//! errors naming the file; a scene with a mesh instanced three times renders and shares one mesh.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use zeroset::aov::Aov;
use zeroset::mesh_io::{load_mesh, read_mesh, MeshDesc};
use zeroset::registry::{BuildContext, SceneShape};
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

fn corners(data: &zeroset::mesh_io::MeshData, t: usize) -> [[f32; 3]; 3] {
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
    expect_error("not_a_mesh.stl", b"solid", &["unknown mesh format"]);
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
