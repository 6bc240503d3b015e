//! Writes a PLY mesh as binary STL, ASCII STL, OFF and GLB, and times loading each against the
//! PLY (read and BVH build, `zeroset::scene::mesh_io::load_mesh`), median of alternating rounds.
//!
//!     cargo run --release --example mesh_formats -- MESH.ply OUT_DIR [ROUNDS]
//!
//! Also writes `OUT_DIR/<name>.ron` scenes (the PLY's camera-less twins) for `zeroset query`.

#[path = "../tests/support/mesh_writers.rs"]
mod writers;

use std::path::{Path, PathBuf};
use std::time::Instant;
use zeroset::scene::mesh_io::{load_mesh, read_mesh};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: mesh_formats MESH.ply OUT_DIR [ROUNDS]");
        std::process::exit(2);
    }
    let (ply, out) = (Path::new(&args[1]), Path::new(&args[2]));
    let rounds: usize = args.get(3).map_or(7, |r| r.parse().expect("ROUNDS"));
    std::fs::create_dir_all(out).unwrap();
    let d = read_mesh(ply).unwrap();
    let stem = ply.file_stem().unwrap().to_string_lossy().to_string();
    let files: Vec<(PathBuf, Vec<u8>)> = vec![
        (
            out.join(format!("{stem}.stl")),
            writers::binary_stl(&d.vertices, &d.indices, b"zeroset"),
        ),
        (
            out.join(format!("{stem}_ascii.stl")),
            writers::ascii_stl(&d.vertices, &d.indices),
        ),
        (out.join(format!("{stem}.off")), writers::off(&d.vertices, &d.indices)),
        (out.join(format!("{stem}.glb")), writers::glb(&d.vertices, &d.indices)),
    ];
    let mut paths = vec![std::fs::canonicalize(ply).unwrap()];
    for (path, bytes) in &files {
        writers::write(path, bytes);
        paths.push(path.clone());
    }
    for path in &paths {
        let name = path.file_name().unwrap().to_string_lossy().replace('.', "_");
        let ron = format!(
            "Scene(camera: (), objects: [(shape: Mesh(path: {:?}, normals: false))])\n",
            path.display()
        );
        std::fs::write(out.join(format!("{name}.ron")), ron).unwrap();
    }
    let mut times = vec![Vec::new(); paths.len()];
    for _ in 0..rounds {
        for (k, path) in paths.iter().enumerate() {
            let start = Instant::now();
            let mesh = load_mesh(path, false).unwrap();
            times[k].push(start.elapsed().as_secs_f64());
            assert_eq!(mesh.triangle_count(), d.indices.len());
        }
    }
    let median = |t: &mut Vec<f64>| {
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    let base = median(&mut times[0].clone());
    println!(
        "{} triangles, {rounds} alternating rounds, median load (read + BVH):",
        d.indices.len()
    );
    for (path, t) in paths.iter().zip(&mut times) {
        let m = median(t);
        let size = std::fs::metadata(path).unwrap().len();
        println!(
            "  {:<28} {:>11} bytes  {:8.3} s  {:5.2}x the PLY",
            path.file_name().unwrap().to_string_lossy(),
            size,
            m,
            m / base
        );
    }
}
