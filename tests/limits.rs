//! The command line under hostile sizes and inputs: a render whose sample buffers exceed an
//! address-space limit (`ulimit -v`) is refused with the estimate (exit 1, never an abort), and
//! scene and pose files that are devices, FIFOs or over the input limit are refused at once,
//! with the file, what was being read, the limit and how to raise it.

mod support;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use support::{assert_fails, bin, p, write_file};
use zeroset::resources::{human_bytes, INPUT_LIMIT_VAR};

/// Runs `command` to completion, or kills it after `limit` and fails.
fn run_within(mut command: Command, limit: Duration, what: &str) -> Output {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let start = Instant::now();
    while child.try_wait().expect("waited on").is_none() {
        if start.elapsed() > limit {
            child.kill().expect("killed");
            panic!("{what}: still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("its output")
}

/// The binary with `args` under an address-space limit of `kib` KiB (`ulimit -v`).
#[cfg(target_os = "linux")]
fn under_ulimit_v(kib: u64, args: &[&str]) -> Command {
    let mut c = Command::new("bash");
    c.current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_zeroset"))
        .args(args);
    c
}

#[cfg(target_os = "linux")]
#[test]
fn sample_buffers_beyond_the_address_space_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let args = [
        "render",
        "scenes/default.ron",
        "-o",
        p(&out),
        "--width",
        "64",
        "--height",
        "64",
        "--spp",
        "10000000",
        "-t",
        "2",
    ];
    let o = run_within(
        under_ulimit_v(2 << 20, &args),
        Duration::from_secs(60),
        "spp 10^7 under 2 GB",
    );
    let err = assert_fails(
        &o,
        &[
            "64x64",
            "10000000 spp",
            "of memory",
            "address-space limit of 2.1 GB (ulimit -v)",
        ],
        "spp 10^7 under ulimit -v 2 GB",
    );
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!out.join("default.exr").exists());
    // the same limit leaves room for an ordinary render
    let o = run_within(
        under_ulimit_v(
            2 << 20,
            &[
                "render",
                "scenes/default.ron",
                "-o",
                p(&out),
                "--width",
                "64",
                "--height",
                "36",
            ],
        ),
        Duration::from_secs(120),
        "a small render under 2 GB",
    );
    support::assert_ok(&o, "a small render under ulimit -v 2 GB");
}

/// `zeroset render PATH` for a scene path that is not a regular file: refused at once.
fn assert_scene_refused(path: &Path, kind: &str) {
    let dir = tempfile::tempdir().unwrap();
    let mut c = bin();
    c.args(["render", p(path), "-o", p(&dir.path().join("out"))]);
    let o = run_within(c, Duration::from_secs(30), p(path));
    let err = assert_fails(&o, &[p(path), kind, "a scene file must be a regular file"], p(path));
    assert_eq!(o.status.code(), Some(1), "{err}");
}

#[cfg(target_os = "linux")]
#[test]
fn devices_and_fifos_are_refused_as_scene_and_pose_files_without_waiting() {
    assert_scene_refused(Path::new("/dev/zero"), "a character device");
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("scene.ron");
    let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo runs");
    assert!(made.success());
    // nothing ever writes to it: reading it would wait for ever
    assert_scene_refused(&fifo, "a FIFO");
    // a pose file that is a FIFO
    let scene = write_file(
        dir.path(),
        "views.ron",
        format!(
            "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 8, height: 8), views: [File({:?})], \
             objects: [(shape: Sphere(radius: 1))])",
            p(&fifo)
        ),
    );
    let mut c = bin();
    c.args(["render", p(&scene), "-o", p(&dir.path().join("out"))]);
    let o = run_within(c, Duration::from_secs(30), "a FIFO pose file");
    assert_fails(
        &o,
        &["views[0]", p(&fifo), "a FIFO", "a pose file must be a regular file"],
        "FIFO pose file",
    );
}

#[test]
fn scene_files_over_the_input_limit_are_refused_with_the_way_to_raise_it() {
    let dir = tempfile::tempdir().unwrap();
    let text = "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 8, height: 8), \
                objects: [(shape: Sphere(radius: 1))])";
    let scene = write_file(dir.path(), "small.ron", text);
    let out = dir.path().join("out");
    let mut c = bin();
    c.args(["render", p(&scene), "-o", p(&out)]).env(INPUT_LIMIT_VAR, "100");
    let o = run_within(c, Duration::from_secs(30), "over the limit");
    let err = assert_fails(
        &o,
        &[
            p(&scene),
            &format!("the scene file is {} B ({} bytes)", text.len(), text.len()),
            "over the limit of 100 B (100 bytes)",
            INPUT_LIMIT_VAR,
        ],
        "scene over the input limit",
    );
    assert_eq!(o.status.code(), Some(1), "{err}");
    // raised, it loads
    let mut c = bin();
    c.args(["render", p(&scene), "-o", p(&out), "--no-previews"])
        .env(INPUT_LIMIT_VAR, "1000");
    support::assert_ok(
        &run_within(c, Duration::from_secs(60), "under the limit"),
        "limit raised",
    );
    // a value that is not a number of bytes is named
    let mut c = bin();
    c.args(["render", p(&scene), "-o", p(&out)])
        .env(INPUT_LIMIT_VAR, "lots");
    let o = run_within(c, Duration::from_secs(30), "a bad limit");
    assert_fails(&o, &[INPUT_LIMIT_VAR, "\"lots\"", "not a number of bytes"], "bad limit");
}

/// A small scene for queries, and a directory to put inputs in.
fn query_scene() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(
        dir.path(),
        "q.ron",
        "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 8, height: 8), \
         objects: [(shape: Sphere(radius: 1))])",
    );
    (dir, scene)
}

/// Ray files (CSV and `.npy`), pixel files and mesh files that are devices or FIFOs are refused
/// at once, naming the file and its kind; nothing waits on the FIFO (no writer ever opens it).
#[cfg(target_os = "linux")]
#[test]
fn devices_and_fifos_are_refused_as_ray_pixel_and_mesh_files_without_waiting() {
    let (dir, scene) = query_scene();
    let fifo = dir.path().join("rays.csv");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs")
        .success());
    let out = dir.path().join("hits.csv");
    for (input, kind, what) in [
        ("/dev/zero", "a character device", "a ray file must be a regular file"),
        (p(&fifo), "a FIFO", "a ray file must be a regular file"),
    ] {
        for format in ["csv", "npy"] {
            let mut c = bin();
            c.args([
                "query",
                p(&scene),
                "--rays",
                input,
                "--rays-format",
                format,
                "-o",
                p(&out),
            ]);
            let o = run_within(c, Duration::from_secs(30), input);
            let err = assert_fails(&o, &[input, kind, what], input);
            assert_eq!(o.status.code(), Some(1), "{err}");
        }
        let mut c = bin();
        c.args(["query", p(&scene), "--pixels", input, "-o", p(&out)]);
        let o = run_within(c, Duration::from_secs(30), input);
        assert_fails(&o, &[input, kind, "a pixel file must be a regular file"], input);
    }
    let mesh_fifo = dir.path().join("mesh.obj");
    assert!(Command::new("mkfifo")
        .arg(&mesh_fifo)
        .status()
        .expect("mkfifo runs")
        .success());
    let scene = write_file(
        dir.path(),
        "mesh.ron",
        format!(
            "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 8, height: 8), \
             objects: [(shape: Mesh(path: {:?}))])",
            p(&mesh_fifo)
        ),
    );
    let mut c = bin();
    c.args(["render", p(&scene), "-o", p(&dir.path().join("out"))]);
    let o = run_within(c, Duration::from_secs(30), "a FIFO mesh file");
    assert_fails(
        &o,
        &[p(&mesh_fifo), "a FIFO", "a mesh file must be a regular file"],
        "FIFO mesh file",
    );
}

/// Ray, pixel and mesh files over `ZEROSET_MAX_INPUT_BYTES` are refused with their size, the
/// limit and the variable; a CSV ray input without line ends (standard input from `/dev/zero`)
/// is refused after 64 KiB with its line number, not read until memory runs out.
#[cfg(target_os = "linux")]
#[test]
fn ray_pixel_and_mesh_files_over_the_limit_are_refused_with_the_way_to_raise_it() {
    let (dir, scene) = query_scene();
    let rays = write_file(dir.path(), "rays.csv", "0,0,-5,0,0,1\n".repeat(20));
    let pixels = write_file(dir.path(), "pixels.csv", "4,4\n".repeat(40));
    let out = dir.path().join("hits.csv");
    for (flag, file, what, len) in [
        ("--rays", &rays, "ray file", 260),
        ("--pixels", &pixels, "pixel file", 160),
    ] {
        let mut c = bin();
        c.args(["query", p(&scene), flag, p(file), "-o", p(&out)])
            .env(INPUT_LIMIT_VAR, "150");
        let o = run_within(c, Duration::from_secs(30), what);
        let err = assert_fails(
            &o,
            &[
                p(file),
                &format!("the {what} is {len} B ({len} bytes)"),
                "over the limit of 150 B (150 bytes)",
                INPUT_LIMIT_VAR,
            ],
            what,
        );
        assert_eq!(o.status.code(), Some(1), "{err}");
        let mut c = bin();
        c.args(["query", p(&scene), flag, p(file), "-o", p(&out)])
            .env(INPUT_LIMIT_VAR, "1000");
        support::assert_ok(&run_within(c, Duration::from_secs(30), what), what);
        // raised, every row is there (a header and 20 rays or 40 pixels), each a hit; the rays
        // from z = −5 along +z meet the unit sphere at t = 4 (written `4e0`)
        let hits = std::fs::read_to_string(&out).unwrap();
        let rows: Vec<&str> = hits.lines().skip(1).collect();
        assert_eq!(rows.len(), if flag == "--rays" { 20 } else { 40 }, "{hits}");
        assert!(rows.iter().all(|r| r.starts_with("1,")), "{hits}");
        if flag == "--rays" {
            assert!(rows.iter().all(|r| r.starts_with("1,4e0,")), "{hits}");
        }
    }
    // a triangle after 1000 bytes of comment: larger than the scene naming it
    let text = format!("{}v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "# padding\n".repeat(100));
    let obj = write_file(dir.path(), "tri.obj", &text);
    let mesh_scene = write_file(
        dir.path(),
        "mesh.ron",
        format!(
            "Scene(camera: (eye: (0, 0, -5), look_at: (0, 0, 0), width: 8, height: 8), \
             objects: [(shape: Mesh(path: {:?}))])",
            p(&obj)
        ),
    );
    let limit = std::fs::metadata(&mesh_scene).unwrap().len() + 10;
    assert!(limit < text.len() as u64);
    let mut c = bin();
    c.args(["render", p(&mesh_scene), "-o", p(&dir.path().join("m"))])
        .env(INPUT_LIMIT_VAR, limit.to_string());
    let o = run_within(c, Duration::from_secs(30), "mesh over the limit");
    assert_fails(
        &o,
        &[
            p(&obj),
            &format!(
                "the mesh file is {} ({} bytes)",
                human_bytes(text.len() as u64),
                text.len()
            ),
            &format!("over the limit of {limit} B ({limit} bytes) for mesh files"),
            INPUT_LIMIT_VAR,
        ],
        "mesh over the limit",
    );
    // standard input without line ends
    let mut c = Command::new("bash");
    c.arg("-c")
        .arg(format!(
            "exec \"$0\" query {} --rays - --rays-format csv -o {} < /dev/zero",
            p(&scene),
            p(&out)
        ))
        .arg(env!("CARGO_BIN_EXE_zeroset"));
    let o = run_within(c, Duration::from_secs(30), "/dev/zero on stdin");
    assert_fails(&o, &["-:1", "line longer than 64 KiB"], "a line without end");
}
