//! Interrupts clean up: SIGINT or SIGTERM during `zeroset render` or `zeroset query -o x.npy`
//! removes the hidden temporary outputs and leaves the previous outputs byte for byte; the
//! temporary files a SIGKILLed run left are removed by the next run writing the same output.

#![cfg(unix)]

mod support;

use std::io::Write;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use support::{bin, write_file, FOUR_K_SPHERE_AND_PLANE};

/// A 4K frame (rendered at 4 spp here): several seconds of tracing on two threads, so a signal
/// sent once the temporary EXR exists finds the render still running.
const SCENE: &str = FOUR_K_SPHERE_AND_PLANE;

/// The outputs of a render of `scene.ron` other than `scene.cameras.json` (which is written,
/// whole, before the trace starts).
const OUTPUTS: [&str; 4] = ["scene.exr", "scene.beauty.png", "scene.depth.png", "scene.normal.png"];

/// Hidden temporary files in `dir` (`.NAME.XXXXXX.tmp`).
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().ends_with(".tmp"))
        .collect();
    found.sort();
    found
}

/// Waits (at most 60 s) until a temporary file whose name starts with `prefix` is in `dir`;
/// fails if `child` ends first.
fn wait_for_temporary(child: &mut Child, dir: &Path, prefix: &str) {
    let started = Instant::now();
    loop {
        if temporaries(dir)
            .iter()
            .any(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix))
        {
            return;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before its temporary file {prefix}… appeared");
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no temporary file {prefix}…"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Sends `signal` (`INT`, `TERM`, `KILL`) to `child`.
fn send(child: &Child, signal: &str) {
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success(), "kill -{signal}");
}

/// Old contents of the outputs, recognisable and unlike anything a render writes.
fn plant_old_outputs(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    std::fs::create_dir_all(dir).unwrap();
    OUTPUTS
        .iter()
        .map(|name| {
            let path = dir.join(name);
            let bytes = format!("previous {name}, never to be replaced by a partial file\n").into_bytes();
            std::fs::write(&path, &bytes).unwrap();
            (path, bytes)
        })
        .collect()
}

fn render(scene: &Path, out: &Path) -> Command {
    let mut c = bin();
    c.args(["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--spp", "4", "-t", "2"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

#[test]
fn sigint_and_sigterm_during_a_render_leave_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "scene.ron", SCENE);
    let out = dir.path().join("out");
    let old = plant_old_outputs(&out);
    // each signal at two moments: as soon as the EXR's temporary file appears, and later in the
    // trace (its rows and the previews' files being written)
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        for delay_ms in [0, 400] {
            let mut child = render(&scene, &out).spawn().unwrap();
            wait_for_temporary(&mut child, &out, ".scene.exr.");
            std::thread::sleep(Duration::from_millis(delay_ms));
            send(&child, signal);
            let o = child.wait_with_output().unwrap();
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(
                o.status.code(),
                Some(code),
                "SIG{signal} after {delay_ms} ms: exit {:?} (still running when signalled?)\n{stderr}",
                o.status
            );
            assert!(stderr.contains("interrupted"), "{stderr}");
            assert_eq!(
                temporaries(&out),
                Vec::<PathBuf>::new(),
                "SIG{signal} after {delay_ms} ms"
            );
            for (path, bytes) in &old {
                assert_eq!(&std::fs::read(path).unwrap(), bytes, "{} changed", path.display());
            }
        }
    }
}

#[test]
fn a_killed_runs_temporary_files_are_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "scene.ron", SCENE);
    let out = dir.path().join("out");
    let old = plant_old_outputs(&out);
    let mut child = render(&scene, &out).spawn().unwrap();
    wait_for_temporary(&mut child, &out, ".scene.exr.");
    send(&child, "KILL");
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(9));
    let left = temporaries(&out);
    assert!(!left.is_empty(), "a SIGKILL cannot clean up");
    for (path, bytes) in &old {
        assert_eq!(&std::fs::read(path).unwrap(), bytes, "{} changed", path.display());
    }
    // a temporary file of another output, and one whose writer is alive, are left alone
    let unrelated = write_file(&out, ".other.exr.AbC123.tmp", "another output's");
    let live = write_file(&out, ".scene.exr.LiVe99.tmp", "a live writer's");
    let holder = std::fs::File::open(&live).unwrap();
    fs4::fs_std::FileExt::lock_exclusive(&holder).unwrap();

    let o = bin()
        .args(["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--width", "64", "--height", "36"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        temporaries(&out),
        vec![unrelated, live],
        "the stale files {left:?} are gone"
    );
    for (path, bytes) in &old {
        assert_ne!(&std::fs::read(path).unwrap(), bytes, "{} replaced", path.display());
    }
}

#[test]
fn sigint_and_sigterm_during_a_query_leave_the_old_npy() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "scene.ron", SCENE);
    let npy = dir.path().join("hits.npy");
    let old = b"previous hits.npy\n".to_vec();
    std::fs::write(&npy, &old).unwrap();
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        // the rays come through a pipe that stays open: the query is still running, its
        // temporary output open, when the signal arrives
        let mut child = bin()
            .args([
                "query",
                scene.to_str().unwrap(),
                "--rays",
                "-",
                "-o",
                npy.to_str().unwrap(),
            ])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        for i in 0..2000 {
            writeln!(stdin, "0,1,-6,{},0,1", f64::from(i) * 1e-4).unwrap();
        }
        stdin.flush().unwrap();
        wait_for_temporary(&mut child, dir.path(), ".hits.npy.");
        std::thread::sleep(Duration::from_millis(200));
        send(&child, signal);
        let o = child.wait_with_output().unwrap();
        drop(stdin);
        assert_eq!(o.status.code(), Some(code), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(temporaries(dir.path()), Vec::<PathBuf>::new(), "SIG{signal}");
        assert_eq!(std::fs::read(&npy).unwrap(), old);
    }
}
