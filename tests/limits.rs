//! The command line under hostile sizes and inputs: a render whose sample buffers exceed an
//! address-space limit (`ulimit -v`) is refused with the estimate (exit 1, never an abort), and
//! scene and pose files that are devices, FIFOs or over the input limit are refused at once,
//! with the file, what was being read, the limit and how to raise it.

mod support;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use support::{assert_fails, bin, p, write_file};
use zeroset::resources::INPUT_LIMIT_VAR;

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
